"""``trumans eval synthesis``: the synthesis benchmark (the sampling issue's figures).

Rooms: procedural rooms whose seeds (``EVAL_ROOM_SEEDS``) are not among the training rooms (the
dataset builder draws 32-bit hashed seeds), so every seat height and layout is unseen. Plans: per
room, a seeded plan "walk to a seat, sit, stand up, walk to a far point, drink, walk back"
(``trumans.sample.cli.default_plan`` with a seeded start). Every figure of ``trumans.eval.synthesis_metrics`` is
averaged over the plans; speed is measured on the same plans: ``seconds_per_episode`` of the fast
sampler (conditions encoded once per episode, ``--steps`` respaced DDIM steps, inference mode)
and of the naive one (full T-step ancestral sampling, conditions recomputed at every step, the
same classifier-free guidance scales, so both sample the same distribution) over
the same episodes of the first plan, in this run (three interleaved runs of each, the median; the
time of the episodes with their post-processing, not of the plan's path search).
``speedup_vs_naive`` compares them like for like: the fast sampler with its goal guidance off (the
naive sampler has none; the guidance's backward passes cost 6-8x the unguided step);
``speedup_guided_vs_naive`` times it as configured;
``realtime_factor`` = seconds of motion per
second of sampling. ``fid`` / ``diversity`` / ``action_acc`` use the project's motion encoder
(``trumans.eval.motion_encoder``) when it is shipped; the real-data value sits beside each.
"""
from __future__ import annotations

from trumans.checkpoint_args import add_checkpoint_arguments, resolve_checkpoint
from trumans.common_args import add_device_argument
from trumans.threads import add_threads_argument, set_threads
import argparse
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config
from trumans import argtypes
from trumans.paths import MODELS_DIR

if TYPE_CHECKING:
    from trumans.sample.sampler import SamplerConfig

__all__ = ["add_arguments", "run", "EVAL_ROOM_SEEDS", "fid_figures", "write_windows", "read_windows", "load_reference",
           "eval_plan"]

EVAL_ROOM_SEEDS: tuple[int, ...] = (9001, 9002, 9003, 9004, 9005, 9006)
SAME_SIZE_DRAWS = 10  # draws of train windows averaged for the real_*_same_size figures
REFERENCE_FILE = MODELS_DIR / "synthesis_reference.npz"


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_checkpoint_arguments(p, "generator checkpoint (default: the shipped one)")
    add_threads_argument(p)
    add_device_argument(p)
    p.add_argument("--rooms", type=int, default=3, help=f"how many evaluation rooms (1-{len(EVAL_ROOM_SEEDS)})")
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    p.add_argument("--steps", type=int, default=d.steps, help=f"denoising steps of the fast sampler (default {d.steps})")
    p.add_argument("--eta", type=float, default=d.eta, help="DDIM eta of the fast sampler (0 deterministic, 1 "
                   "ancestral: with --steps 100 --goal-guidance 0 it samples what the naive sampler samples; "
                   f"default {d.eta:g})")
    p.add_argument("--naive-episodes", type=int, default=3, help="episodes timed with the naive sampler (0 = skip)")
    add_guidance_arguments(p)
    p.add_argument("--ablation", action="append", default=[], metavar="NAME=CHECKPOINT",
                   help="also evaluate an ablation checkpoint (e.g. no_progress=runs/noprog/checkpoint.pt)")
    p.add_argument("--data", default=None, help="dataset whose test split is the real reference for fid "
                   "(default: the shipped models/synthesis_reference.npz)")
    p.add_argument("--motion-encoder", default=None, metavar="PATH",
                   help="motion encoder of fid / diversity / action_acc (default: the shipped one; needs --data)")
    add_postprocess_arguments(p)
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--save-windows", default=None, metavar="PATH",
                   help="also write the generated windows' motion-encoder features and labels (.npz) there, "
                        "e.g. to pool seeds: python benchmarks/pooled_fid.py")
    p.add_argument("--json", action="store_true")


def eval_plan(sc, seed: int):
    """The seeded evaluation plan of a ``SampleScene`` (see the module doc)."""
    from trumans.sample.cli import default_plan
    from trumans.sample.plan import plan_from_dict

    d = default_plan(sc)
    rng = np.random.default_rng(seed)
    free = sc.walkmap.centers(np.argwhere(sc.walkmap.walkable))
    d["start"] = free[rng.integers(len(free))].tolist()
    d["heading"] = float(rng.uniform(-np.pi, np.pi))
    d["steps"][-1]["to"] = d["start"]
    return plan_from_dict(d, name=f"eval_{seed}")


def evaluate(ckpt_path, rooms: int, seed: int, naive_episodes: int, config: SamplerConfig | None = None,
             reference: str | None = None, encoder: str | None = None, save_windows: str | None = None,
             device: str = "cpu") -> dict:
    """The figures (see the module doc); ``config``: the fast sampler's (default ``SamplerConfig()``,
    what ``trumans sample`` does; the naive sampler takes its classifier-free guidance scales);
    ``encoder``: motion encoder checkpoint of fid / action_acc (default: the shipped one);
    ``save_windows``: a path for the generated windows' encoder features and labels (``write_windows``)."""
    import torch

    from trumans.model.checkpoint import load_checkpoint

    from trumans.sample.rollout import sample_plan
    from trumans.sample.sampler import EpisodeSampler, SamplerConfig
    from trumans.sample.scene_input import load_sample_scene
    from trumans.eval.synthesis_metrics import motion_figures

    config = SamplerConfig() if config is None else config
    ckpt = load_checkpoint(ckpt_path, kind="generator")
    torch.set_grad_enabled(False)
    per, results, times, motion_s = [], [], 0.0, 0.0
    first = None
    for r, room_seed in enumerate(EVAL_ROOM_SEEDS[:rooms]):
        sc = load_sample_scene(f"room:{room_seed}")
        plan = eval_plan(sc, seed * 1000 + r)
        sampler = EpisodeSampler(ckpt, sc.grids, config, device=device)
        res = sample_plan(ckpt, sampler, sc.scene, sc.walkmap, plan, seed=seed + r)
        per.append(motion_figures(res, sc))
        results.append(res)
        times += res.seconds
        motion_s += res.joints.shape[1] / res.fps
        if first is None:
            first = (sc, plan, res)
    figs = {}
    for key in per[0]:
        vals = [p[key] for p in per if p[key] is not None and np.isfinite(p[key])]
        figs[key] = round(float(np.mean(vals)), 4) if vals else None
    eps = sum(r.episodes for r in results)
    figs["seconds_per_episode"] = round(times / max(eps, 1), 4)
    figs["realtime_factor"] = round(motion_s / max(times, 1e-9), 2)
    figs["episodes"] = eps
    figs["seconds_of_motion"] = round(motion_s, 1)
    if naive_episodes > 0:
        sc, plan, res = first
        naive = EpisodeSampler(ckpt, sc.grids, SamplerConfig(steps=ckpt.diffusion_config.steps, eta=1.0, naive=True,
                                                             goal_guidance=0.0, scene_scale=config.scene_scale,
                                                             action_scale=config.action_scale), device=device)
        fast = EpisodeSampler(ckpt, sc.grids, config, device=device)
        samplers = {"fast": fast, "naive": naive}
        if config.goal_guidance > 0:  # the same fast sampler without goal guidance: like for like with the naive one
            samplers["unguided"] = EpisodeSampler(ckpt, sc.grids, replace(fast.config, goal_guidance=0.0), device=device)
        t = {name: [] for name in samplers}
        for rep in range(3):  # interleaved, the median of each: the machine's speed drifts
            for name, s in samplers.items():
                short = sample_plan(ckpt, s, sc.scene, sc.walkmap, plan, seed=seed + rep, max_seconds=1e9,
                                    max_episodes=naive_episodes)
                t[name].append(short.seconds_per_episode)  # the episodes' time; the plan's path search is not in it
                if name == "naive" and rep == 0:
                    figs["naive_goal_err_cm"] = motion_figures(short, sc)["goal_err_cm"]
        t = {k: float(np.median(v)) for k, v in t.items()}
        figs["naive_seconds_per_episode"] = round(t["naive"], 4)
        # like for like: the naive sampler has no goal guidance (its 3 backward passes a step are an add-on)
        figs["speedup_vs_naive"] = round(t["naive"] / t.get("unguided", t["fast"]), 2)
        figs["speedup_guided_vs_naive"] = round(t["naive"] / t["fast"], 2)
    figs.update(_encoder_figures(results, list(ckpt.vocabulary), reference, encoder, save_windows))
    return figs


def reference_windows(enc, data: str, train_windows: int = 3000, seed: int = 0) -> dict[str, np.ndarray]:
    """The fid reference of a dataset: motion-encoder features (N, D) and window labels (N,) of its
    test split's clips, and of at most ``train_windows`` windows of its train split (seeded) for the
    real-vs-real value. What ``models/synthesis_reference.npz`` stores."""
    from trumans.dataset import Dataset
    from trumans.eval.motion_encoder import split_features_and_labels

    ds = Dataset(data)
    f, y = split_features_and_labels(enc, ds, "test")
    tf, ty = split_features_and_labels(enc, ds, "train")
    keep = np.sort(np.random.default_rng(seed).choice(len(tf), min(train_windows, len(tf)), replace=False))
    return {"features": f.astype(np.float32), "labels": y, "train_features": tf[keep].astype(np.float32),
            "train_labels": ty[keep], "data_hash": np.str_(ds.hash), "split": np.str_("test")}


def load_reference() -> dict[str, np.ndarray] | None:
    """The shipped fid reference (``REFERENCE_FILE``, what ``reference_windows`` computes), or None without one."""
    if not REFERENCE_FILE.is_file():
        return None
    with np.load(REFERENCE_FILE, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _encoder_figures(results, vocabulary: list[str], reference: str | None, encoder: str | None = None,
                     save_windows: str | None = None) -> dict:
    """fid / diversity / action_acc of the generated clips (first sample of each plan) with the
    motion encoder (default: the shipped one), and the real data's values beside them (``fid_figures``).
    save_windows: also write the generated windows' features and labels there (``save_windows``)."""
    from trumans.eval.motion_encoder import action_acc, diversity, load_motion_encoder

    enc = load_motion_encoder(encoder)
    fps = results[0].fps
    feats = np.concatenate([enc.encode(r.joints[0], fps)[0] for r in results])
    probs = np.concatenate([enc.classify(r.joints[0], fps)[0] for r in results])
    labels = np.concatenate([enc.window_labels(r.labels[0], vocabulary, fps)[0] for r in results])
    if save_windows is not None:
        write_windows(save_windows, feats, labels)
    out = {"diversity": round(diversity(feats), 3), "action_acc": round(action_acc(probs, labels), 3),
           "real_action_acc": round(float(enc.info.get("test_acc", float("nan"))), 3)}
    if reference is None and encoder is not None:
        raise ValueError("the shipped reference features belong to the shipped motion encoder; with --motion-encoder "
                         "give --data DATASET (its test split is the reference)")
    ref = reference_windows(enc, reference) if reference is not None else load_reference()
    if ref is None:
        return {**out, "fid": None, "fid_note": f"no reference features: give --data DATASET or ship {REFERENCE_FILE}"}
    out["real_fid"] = round(float(enc.info.get("fid_train_vs_test", float("nan"))), 3)
    out["real_diversity"] = round(diversity(ref["features"].astype(np.float64)), 3)
    return {**out, **fid_figures(feats, labels, ref)}


def fid_figures(feats: np.ndarray, labels: np.ndarray, ref: dict[str, np.ndarray]) -> dict:
    """Generated window features (N, D) and dominant-action labels (N,) against a reference
    (``reference_windows`` / the shipped file): ``fid``; ``fid_matched``: fid against the real test
    windows weighted to the generated windows' action mix (the plans walk, sit and drink; the test
    split also lies, opens doors, carries ...), with ``real_fid_matched``, train windows against
    test windows under the same weights, beside it; ``real_fid_same_size`` /
    ``real_fid_matched_same_size``: the same for train windows drawn to the generated set's size and
    action mix (``like_sample``; mean of ``SAME_SIZE_DRAWS`` draws): the fair real value for a set of
    a few dozen windows, whose Fréchet distance is biased upward."""
    from trumans.eval.motion_encoder import fid, like_sample, matched_weights

    real = ref["features"].astype(np.float64)
    out = {"fid": round(fid(real, feats), 3)}
    if "labels" in ref and "train_features" in ref:
        w_test = matched_weights(ref["labels"], labels)
        out["fid_matched"] = round(fid(real, feats, real_weights=w_test), 3)
        out["real_fid_matched"] = round(fid(real, ref["train_features"].astype(np.float64), real_weights=w_test,
                                            gen_weights=matched_weights(ref["train_labels"], labels)), 3)
        # the same real-vs-real figures for train windows of the generated set's size and action mix
        rng, same, same_m = np.random.default_rng(0), [], []
        for _ in range(SAME_SIZE_DRAWS):
            sub = ref["train_features"][like_sample(ref["train_labels"], labels, rng)].astype(np.float64)
            same.append(fid(real, sub))
            same_m.append(fid(real, sub, real_weights=w_test))
        out["real_fid_same_size"] = round(float(np.mean(same)), 3)
        out["real_fid_matched_same_size"] = round(float(np.mean(same_m)), 3)
    out["windows"] = int(len(feats))
    return out


def write_windows(path: str | Path, feats: np.ndarray, labels: np.ndarray) -> None:
    """Write generated windows (``--save-windows``): features (N, D) float32, labels (N,) int64."""
    from trumans.sequence import atomic_write

    f, y = np.asarray(feats, np.float32), np.asarray(labels, np.int64).ravel()
    if f.ndim != 2 or len(f) != len(y):
        raise ValueError(f"need features (N, D) and labels (N,), got {f.shape} and {y.shape}")

    def _write(tmp: str) -> None:
        with open(tmp, "wb") as fh:  # a file object: np.savez would add ".npz" to a name
            np.savez(fh, features=f, labels=y)

    atomic_write(path, _write)


def read_windows(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(features (N, D) float32, labels (N,) int64) written by ``write_windows``; never runs code."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"window file {path} does not exist; write it with `trumans eval synthesis --save-windows`")
    with np.load(path, allow_pickle=False) as z:
        if not {"features", "labels"} <= set(z.files):
            raise ValueError(f"{path} holds {sorted(z.files)}, not the features and labels of --save-windows")
        f, y = z["features"], z["labels"]
    if f.ndim != 2 or y.shape != (len(f),) or not np.isfinite(f).all():
        raise ValueError(f"{path}: need finite features (N, D) and labels (N,), got {f.shape} and {y.shape}")
    return f.astype(np.float32), y.astype(np.int64)


MAX_NAIVE_EPISODES = 100  # --naive-episodes: each is a full T-step ancestral episode, seconds to minutes


def _check_inputs(args: argparse.Namespace, default_checkpoint: Path) -> list[tuple[str, str]]:
    """Every file argument read before any sampling (minutes): the checkpoints (loaded: kind and
    digest), ``--ablation NAME=CHECKPOINT`` (distinct names), ``--motion-encoder``, ``--data`` (a
    dataset with a test split) and ``--save-windows`` (a file in an existing folder). Returns the
    ablations as (name, path)."""
    from trumans.model.checkpoint import load_checkpoint

    ablations = []
    for spec in args.ablation:
        name, _, path = spec.partition("=")
        if not name or not path:
            raise ValueError(f"--ablation must be NAME=CHECKPOINT, got {spec!r}")
        if name in dict(ablations):
            raise ValueError(f"--ablation {name} is given twice; give each ablation one name")
        ablations.append((name, path))
    for what, path in [("", args.checkpoint or default_checkpoint), *((f"--ablation {n}: ", p) for n, p in ablations)]:
        try:
            steps = load_checkpoint(path, kind="generator").diffusion_config.steps
        except (FileNotFoundError, ValueError) as e:
            raise type(e)(f"{what}{e}") from None
        if args.steps > steps:
            raise ValueError(f"--steps {args.steps} is more than the {steps} diffusion steps of {what}{path}; "
                             f"give --steps <= {steps}")
    if args.motion_encoder is not None:
        from trumans.eval.motion_encoder import load_motion_encoder

        load_motion_encoder(args.motion_encoder)
    if args.data is not None:
        from trumans.dataset import Dataset

        if not Dataset(args.data).split("test"):
            raise ValueError(f"--data {args.data} has no test split sequences (the fid reference); give a dataset "
                             f"built with test rooms")
    if args.save_windows is not None:
        p = Path(args.save_windows)
        if p.is_dir() or not p.parent.is_dir():
            raise ValueError(f"--save-windows {p} must be a file in an existing folder")
    if args.naive_episodes > MAX_NAIVE_EPISODES:
        raise ValueError(f"--naive-episodes {args.naive_episodes} is more than {MAX_NAIVE_EPISODES} (each is a full "
                         f"T-step episode); give fewer")
    return ablations


def run(args: argparse.Namespace) -> int:
    from trumans.sample.cli import DEFAULT_CHECKPOINT

    resolve_checkpoint(args)
    set_threads(args.threads)

    if not 1 <= args.rooms <= len(EVAL_ROOM_SEEDS):
        raise ValueError(f"--rooms must be in [1, {len(EVAL_ROOM_SEEDS)}], got {args.rooms}")
    if args.steps < 1 or args.naive_episodes < 0 or not 0.0 <= args.eta <= 1.0:
        raise ValueError(f"--steps must be >= 1, --naive-episodes >= 0 and --eta in [0, 1], got {args.steps}, "
                         f"{args.naive_episodes}, {args.eta}")
    if not all(np.isfinite(g) and g >= 0 for g in args.guidance):
        raise ValueError(f"--guidance scales must be finite and >= 0 (1 = plain conditional), got {list(args.guidance)}")
    if args.motion_encoder is not None and args.data is None:
        raise ValueError("the shipped reference features belong to the shipped motion encoder; with --motion-encoder "
                         "give --data DATASET (its test split is the reference)")
    ablations = _check_inputs(args, DEFAULT_CHECKPOINT)
    config = sampler_config(args)
    figs = evaluate(args.checkpoint or DEFAULT_CHECKPOINT, args.rooms, args.seed, args.naive_episodes, config,
                    args.data, args.motion_encoder, args.save_windows, device=args.device)
    for name, path in ablations:
        figs[f"ablation_{name}"] = evaluate(path, args.rooms, args.seed, 0, config, args.data, args.motion_encoder,
                                               device=args.device)
    if args.json:
        from trumans.summary import print_summary

        print_summary(figs)
    else:
        print("\n".join(f"{k}: {v}" for k, v in figs.items()))
    return 0
