"""`trumans eval refine [CHECKPOINT] [--seed S] [--json]`: the HOI filter's benchmark figures.

Held-out data: the dataset's test split cut into clips of ``--clip`` frames (each with its
interacting object, ``trumans.refine.data``), corrupted by the seeded training corruption model, and
refined end to end (resampling, windows, blending). Figures (means over clips and frames):

- ``mpjpe_in_mm`` (observed joints of the tracked input), ``mpjpe_out_mm`` (every frame),
  ``mpjpe_out_observed_mm`` (the input's observed joints), ``mpjpe_savgol_mm`` (Savitzky–Golay,
  order 2, missing frames linearly interpolated first, window tuned on the val split);
- ``accel_err_in`` / ``accel_err_out`` / ``accel_err_savgol``: mean |second difference − the
  truth's| of the joints, mm/frame² (input: where three consecutive frames are observed);
  ``accel_gt`` and ``accel_out``: mean |second difference| of the truth and of the output;
- ``obj_t_err_in_cm`` / ``_out_cm``, ``obj_rot_err_in_deg`` / ``_out_deg``;
- ``hand_obj_dist_cm``: mean |d̂ − d| with d the distance from the nearer hand (wrist / index1) to
  the object, for the output (``hand_obj_dist_in_cm`` for the input);
- ``foot_skate_planted_out_cm`` / ``_savgol_cm`` / ``_gt_cm`` (``trumans.eval.metrics.foot_skate_planted_cm``): how far a foot joint (ankles, feet) slides
  horizontally while the truth's is planted (under 0.1 m/s and within 5 cm of its lowest in the
  clip), summed over each such run and averaged over runs (``trumans.eval.metrics.foot_slides``), cm;
- ``mpjpe_*_ra_mm``: the same, root-aligned (each frame's pelvis moved onto the truth's: a whole-body
  translation such as the corruption's shared drift does not count);
- ``obj_t_err_out_no_rest_cm`` / ``obj_rot_err_out_no_rest_deg`` and ``mpjpe_out_no_drift_mm``
  (default block): the same clips refined without pooling the object's rests
  (``trumans.refine.object_rest``) and without the body-drift correction (``trumans.refine.body_drift``),
  a second run;
- ``mpjpe_out_drift_oracle_mm`` (default block): the drift fit replaced by the truth — the output
  without the fit minus the corruption's true whole-body drift less its clip mean, then the foot
  lock (a third run): the floor for any drift correction from the sequence alone;
- ``frames_per_s``: refined frames per second of wall time, all clips' windows batched
  (``HOIFilter.refine_many``); ``frames_per_s_per_clip`` (default block): one clip per call.

Blocks: the default corruption (every category, the IMU present in ~70 % of clips), ``no_imu``
(no clip has an IMU), ``drift`` (a drift-dominated model the filter was not trained on), and, with
``--ablation CHECKPOINT``, ``ablation`` (e.g. a model trained without the regularisers); with
``--real``, ``real.default`` / ``real.drift``: held-out real motion (the mocap corpus's test split),
body only.

``--families`` runs the body benchmark instead (``trumans.refine.benchmark``: per corruption family
- clean, the training corruption, the independent tracker model and, with ``--kinds``, each of its
error kinds alone - and per motion type, beside a Gaussian and a Savitzky-Golay smoother tuned per
family; on the corpus's held-out subjects, the same with a foreign skeleton, and with ``--data`` the
dataset's test split). It needs no dataset.
"""
from __future__ import annotations

from trumans.checkpoint_args import add_checkpoint_arguments, resolve_checkpoint
from trumans.common_args import add_device_argument
import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from trumans.refine.filter import category_indices
from trumans.refine.post_args import add_post_step_arguments, post_steps_config
from trumans.eval.metrics import foot_skate_planted_cm
from trumans.skeleton import HAND_JOINTS
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["add_arguments", "run", "evaluate", "tune_savgol", "clip_figures", "root_aligned_errors", "real_clips"]

_HANDS = list(HAND_JOINTS)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_checkpoint_arguments(p, "filter checkpoint (default: the shipped models/refine.pt)")
    p.add_argument("--data", default=None, help="dataset folder with val and test splits (default: the one "
                                                "recorded in the checkpoint)")
    p.add_argument("--clip", type=int, default=192, help="frames per evaluation clip (default 192)")
    p.add_argument("--max-clips", type=int, default=120, help="at most this many test clips (default 120)")
    p.add_argument("--steps", type=int, default=2, help="DDIM sampling steps (default 2; 1, 2 and 5 give the same errors, benchmarks/refine_diagnosis.py)")
    p.add_argument("--mode", choices=("noise", "sdedit"), default="noise", help="sampling start (default noise)")
    p.add_argument("--ablation", default=None, metavar="CHECKPOINT", help="a second checkpoint to report as 'ablation'")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="corruption and sampling seed")
    add_post_step_arguments(p)
    add_device_argument(p, runs="the filter network(s); corruption, smoothers and figures are numpy on the CPU")
    p.add_argument("--category", action="append", default=[], metavar="NAME",
                   help="only test clips of this object category (repeatable; default: every category)")
    p.add_argument("--real", action="store_true", help="also evaluate on held-out real motion (the mocap corpus's "
                                                       "test split, body only): blocks real.default and real.drift")
    p.add_argument("--families", action="store_true",
                   help="instead: the body benchmark per corruption family (clean, the training corruption, the "
                        "independent tracker model) and per motion type, beside a Gaussian and a Savitzky-Golay "
                        "smoother tuned per family, on the corpus's held-out subjects and, with --data, the "
                        "dataset's test split (trumans/refine/benchmark.py); needs no dataset")
    p.add_argument("--kinds", action="store_true", help="with --families: also each tracker error kind alone "
                                                        "(on the real clips)")
    p.add_argument("--max-val-clips", type=int, default=20,
                   help="with --families: corpus train clips the smoothers are tuned on (default 20)")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on the last line")


def _joints(f: np.ndarray) -> np.ndarray:
    return f[..., :72].reshape(*f.shape[:-1], 24, 3)


def _fill(x: np.ndarray) -> np.ndarray:
    """Linear interpolation of NaN entries along axis 0 (edges held): (T, D)."""
    x = np.asarray(x, np.float64).copy()
    t = np.arange(len(x))
    for d in range(x.shape[1]):  # loop over feature columns; frames are vectorised by np.interp
        ok = np.isfinite(x[:, d])
        x[:, d] = np.interp(t, t[ok], x[ok, d]) if ok.any() else 0.0
    return x


def _savgol(tracked: np.ndarray, window: int) -> np.ndarray:
    from scipy.signal import savgol_filter

    J = _fill(tracked[:, :72])
    w = min(window, len(J) - (1 - len(J) % 2))
    return savgol_filter(J, w, 2, axis=0) if w > 2 else J


def tune_savgol(clips: list[tuple[np.ndarray, np.ndarray]], windows=range(5, 62, 4)) -> int:
    """The Savitzky–Golay window (odd) with the least MPJPE on (tracked, clean) clip pairs."""
    errs = {w: np.mean([np.linalg.norm(_savgol(tr, w).reshape(-1, 24, 3) - _joints(cl), axis=-1).mean()
                        for tr, cl in clips]) for w in windows}
    return int(min(errs, key=errs.get))


def _rot_deg(a6: np.ndarray, b6: np.ndarray) -> np.ndarray:
    from trumans.rotations import sixd_to_matrix

    c = (np.einsum("...ij,...ij->...", sixd_to_matrix(np.asarray(a6, np.float64)), sixd_to_matrix(np.asarray(b6, np.float64))) - 1) / 2
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def _hand_dist(f: np.ndarray) -> np.ndarray:
    return np.linalg.norm(_joints(f)[:, _HANDS] - f[:, None, 216:219], axis=-1).min(-1)


def root_aligned_errors(J: np.ndarray, Jc: np.ndarray) -> np.ndarray:
    """Per-joint errors (T, 24) m after moving each frame's pelvis onto the truth's (root-aligned
    MPJPE; a whole-body translation such as the corruption's shared drift does not count). NaN where
    the joint or the frame's pelvis is missing."""
    return np.linalg.norm((J - J[:, :1]) - (Jc - Jc[:, :1]), axis=-1)


def clip_figures(tr: np.ndarray, out: np.ndarray, sg: np.ndarray, cl: np.ndarray, fps: float) -> dict[str, float]:
    Jt, Jo, Jc, Js = _joints(tr), _joints(out), _joints(cl), sg.reshape(-1, 24, 3)
    e_in = np.linalg.norm(Jt - Jc, axis=-1)
    obs = np.isfinite(e_in)
    e_in_ra = root_aligned_errors(Jt, Jc)
    acc = lambda J: np.diff(J, 2, axis=0)
    a_c = acc(Jc)
    ea_in = np.linalg.norm(acc(Jt) - a_c, axis=-1)
    seen_t = np.isfinite(tr[:, 216:225]).all(-1)
    return {
        "mpjpe_in_mm": 1000 * e_in[obs].mean(),
        "mpjpe_out_mm": 1000 * np.linalg.norm(Jo - Jc, axis=-1).mean(),
        "mpjpe_out_observed_mm": 1000 * np.linalg.norm(Jo - Jc, axis=-1)[obs].mean(),
        "mpjpe_savgol_mm": 1000 * np.linalg.norm(Js - Jc, axis=-1).mean(),
        "mpjpe_in_ra_mm": 1000 * e_in_ra[np.isfinite(e_in_ra)].mean(),
        "mpjpe_out_ra_mm": 1000 * root_aligned_errors(Jo, Jc).mean(),
        "mpjpe_savgol_ra_mm": 1000 * root_aligned_errors(Js, Jc).mean(),
        "accel_err_in": 1000 * ea_in[np.isfinite(ea_in)].mean(),
        "accel_err_out": 1000 * np.linalg.norm(acc(Jo) - a_c, axis=-1).mean(),
        "accel_err_savgol": 1000 * np.linalg.norm(acc(Js) - a_c, axis=-1).mean(),
        "accel_gt": 1000 * np.linalg.norm(a_c, axis=-1).mean(),
        "accel_out": 1000 * np.linalg.norm(acc(Jo), axis=-1).mean(),
        "obj_t_err_in_cm": 100 * np.linalg.norm(tr[seen_t, 216:219] - cl[seen_t, 216:219], axis=-1).mean(),
        "obj_t_err_out_cm": 100 * np.linalg.norm(out[:, 216:219] - cl[:, 216:219], axis=-1).mean(),
        "obj_rot_err_in_deg": _rot_deg(tr[seen_t, 219:225], cl[seen_t, 219:225]).mean(),
        "obj_rot_err_out_deg": _rot_deg(out[:, 219:225], cl[:, 219:225]).mean(),
        "hand_obj_dist_in_cm": 100 * np.nanmean(np.abs(_hand_dist(np.where(np.isfinite(tr), tr, np.nan)) - _hand_dist(cl))),
        "hand_obj_dist_cm": 100 * np.abs(_hand_dist(out) - _hand_dist(cl)).mean(),
        **{f"foot_skate_planted_{k}_cm": foot_skate_planted_cm(J, Jc, fps) for k, J in (("out", Jo), ("savgol", Js), ("gt", Jc))},
    }


def _mean_finite(values: list[float]) -> float:
    v = np.asarray(values, dtype=np.float64)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else float("nan")


def evaluate(filt, clean: np.ndarray, cats: list[str], corruption, savgol_window: int, seed: int, options,
             per_clip_speed: bool = False, rest_ablation: bool = False) -> dict:
    """Figures of one corruption setting on clean world clips (N, T, 235) with categories. The clips
    are refined together (``HOIFilter.refine_many``: all windows batched); ``frames_per_s`` is that
    run's rate. per_clip_speed: also time the clips one by one (``frames_per_s_per_clip``, the
    one-sequence-per-call rate). rest_ablation: also refine without rest pooling and without the
    body-drift correction and report its object errors (``*_no_rest_*``) and joint error
    (``mpjpe_out_no_drift_mm``), and the true drift's floor (``mpjpe_out_drift_oracle_mm``)."""
    from trumans.refine.corrupt import corrupt

    parts: dict = {}
    tracked = corrupt(clean, filt.fps, np.random.default_rng(seed), corruption, parts=parts)
    t0 = time.perf_counter()
    outs = filt.refine_many(list(tracked), [filt.fps] * len(tracked), list(cats), options)
    seconds = time.perf_counter() - t0
    rows = [clip_figures(tr, out, _savgol(tr, savgol_window), cl, filt.fps) for tr, out, cl in zip(tracked, outs, clean)]
    fig = {k: _mean_finite([r[k] for r in rows]) for k in rows[0]}  # a clip without a planted foot has no skate
    frames = int(sum(len(tr) for tr in tracked))
    fig["frames_per_s"] = frames / max(seconds, 1e-9)
    if per_clip_speed:
        t0 = time.perf_counter()
        for tr, cat in zip(tracked, cats):
            filt.refine_frames(tr, filt.fps, cat, options)
        fig["frames_per_s_per_clip"] = frames / max(time.perf_counter() - t0, 1e-9)
    if rest_ablation and (options.post.rest_pooling.enabled or options.post.body_drift.enabled):
        plain = filt.refine_many(list(tracked), [filt.fps] * len(tracked), list(cats),
                                 replace(options, post=options.post.switched(rest_pooling=False, body_drift=False)))
        fig["mpjpe_out_no_drift_mm"] = float(np.mean([1000 * np.linalg.norm(_joints(o) - _joints(cl), axis=-1).mean()
                                                      for o, cl in zip(plain, clean)]))
        fig["mpjpe_out_drift_oracle_mm"] = _drift_oracle_mm(filt, tracked, clean, cats, parts["body_drift"], options)
        fig["obj_t_err_out_no_rest_cm"] = float(np.mean([100 * np.linalg.norm(o[:, 216:219] - cl[:, 216:219], axis=-1).mean()
                                                         for o, cl in zip(plain, clean)]))
        fig["obj_rot_err_out_no_rest_deg"] = float(np.mean([_rot_deg(o[:, 219:225], cl[:, 219:225]).mean()
                                                            for o, cl in zip(plain, clean)]))
    fig["clips"] = len(rows)
    fig["imu_clips"] = int((tracked[:, 0, 234] > 0.5).sum())
    return fig


def _drift_oracle_mm(filt, tracked: np.ndarray, clean: np.ndarray, cats: list[str], body_drift: np.ndarray,
                     options) -> float:
    """MPJPE (mm) when the body-drift fit is replaced by the truth: the filter's output without the
    fit, minus the corruption's true whole-body drift (B, T, 3) less its clip mean (the constant
    part no estimate from the sequence can see), then the foot lock if on. A floor for any drift
    correction that works from the sequence alone."""
    from trumans.refine.foot_lock import lock_feet

    raw = filt.refine_many(list(tracked), [filt.fps] * len(tracked), list(cats),
                           replace(options, post=options.post.switched(rest_pooling=False, body_drift=False,
                                                                        foot_lock=False)))
    errs = []
    for o, d, cl in zip(raw, body_drift, clean):
        g = o.copy()
        g[:, :72] = (_joints(o) - (d - d.mean(0))[:, None]).reshape(len(o), -1)
        if options.post.foot_lock.enabled:
            g = lock_feet(g, filt.fps, options.post.foot_lock)
        errs.append(1000 * np.linalg.norm(_joints(g) - _joints(cl), axis=-1).mean())
    return float(np.mean(errs))


def _clips(data: str, split: str, clip: int, fps: float, categories: list[str], max_clips: int, seed: int):
    from trumans.refine.corrupt import add_clean_imu
    from trumans.refine.data import load_filter_windows

    w = load_filter_windows(data, split, clip, clip, fps, categories)
    idx = np.arange(len(w))
    if len(idx) > max_clips:
        idx = np.sort(np.random.default_rng(seed).choice(idx, max_clips, replace=False))
    clean, _, cat = w.batch(idx)
    return add_clean_imu(clean, fps), [categories[c] for c in cat]


def real_clips(clip: int, max_clips: int, seed: int) -> np.ndarray:
    """Held-out real-motion clips (N, clip, 235) at 30 fps: the mocap corpus's test split
    (``trumans.mocap_corpus``, subjects never trained on) cut into ``clip``-frame pieces; joints
    only: rotations missing (NaN), no IMU, and the object a still placeholder at the origin (the
    filter needs an observed object; the body figures do not read it), as ``benchmark`` does."""
    from trumans.refine.frame import pack_frames
    from trumans.mocap_corpus import load_corpus

    pieces = []
    for c in load_corpus(split="test"):
        if abs(c.fps - 30.0) > 1e-6:
            raise ValueError(f"corpus clip {c.name} is at {c.fps} fps; the real-motion evaluation expects 30")
        for s in range(0, len(c.joints) - clip + 1, clip):
            J = c.joints[s:s + clip]
            pieces.append(pack_frames(J, None, np.broadcast_to(np.eye(4), (clip, 4, 4))))
    idx = np.arange(len(pieces))
    if len(idx) > max_clips:
        idx = np.sort(np.random.default_rng(seed).choice(idx, max_clips, replace=False))
    return np.stack([pieces[i] for i in idx])


_BODY_KEYS = ("mpjpe_in_mm", "mpjpe_out_mm", "mpjpe_out_observed_mm", "mpjpe_savgol_mm", "mpjpe_in_ra_mm",
              "mpjpe_out_ra_mm", "mpjpe_savgol_ra_mm", "accel_err_in", "accel_err_out", "accel_err_savgol",
              "accel_gt", "accel_out", "foot_skate_planted_out_cm", "foot_skate_planted_savgol_cm", "foot_skate_planted_gt_cm", "frames_per_s", "clips")


def evaluate_real(filt, clip: int, max_clips: int, savgol_window: int, seed: int, options) -> dict:
    """Body-only figures on held-out real motion: the default corruption and the drift-dominated one
    (both without an object IMU: there is no object). The object's category is the filter's first."""
    import warnings

    from trumans.refine.corrupt import CorruptionConfig

    clean = real_clips(clip, max_clips, seed)
    cats = [filt.categories[0]] * len(clean)
    res = {}
    with warnings.catch_warnings():  # the object columns are all missing: their means are NaN and dropped
        warnings.simplefilter("ignore", RuntimeWarning)
        for name, cfg in (("default", CorruptionConfig().without_imu()),
                          ("drift", replace(CorruptionConfig.drift(), p_no_imu=1.0))):
            fig = evaluate(filt, clean, cats, cfg, savgol_window, seed, options)
            res[name] = {k: fig[k] for k in _BODY_KEYS}
    return res


def run_families(args: argparse.Namespace, filt, opts) -> int:
    """``--families``: the body benchmark (``trumans.refine.benchmark``) on real and, with ``--data``,
    synthetic clips; prints one table per family and clip set."""
    from trumans.refine.benchmark import (FIGURES, MOTION_TYPES, benchmark, family_names, foreign_skeleton,
                                          real_body_clips, synthetic_body_clips)

    if args.max_val_clips < 1 or args.max_clips < 1:
        raise ValueError(f"--max-clips and --max-val-clips must be >= 1, got {args.max_clips}, {args.max_val_clips}")
    if args.data and not Path(args.data).is_dir():
        raise FileNotFoundError(f"--data {args.data!r} is not a folder; pass a dataset with val and test splits")
    real = (real_body_clips("test", args.max_clips, args.seed), real_body_clips("train", args.max_val_clips, args.seed))
    sets = {"real": real, "foreign": (foreign_skeleton(real[0]), foreign_skeleton(real[1]))}
    if args.data:
        sets["synthetic"] = (synthetic_body_clips(args.data, "test", filt.fps)[:args.max_clips],
                             synthetic_body_clips(args.data, "val", filt.fps)[:args.max_val_clips])
    t0 = time.perf_counter()
    res: dict = {"checkpoint": str(args.checkpoint or "models/refine.pt"), "seed": args.seed, "families": {},
                 "post_config": opts.post.to_dict()}
    for name, (test, val) in sets.items():  # each tracker kind alone on the real clips only (time)
        fams = family_names(args.kinds and name == "real")
        res["families"][name] = benchmark(filt, test, val, fams, args.seed, opts)
        res["families"][name]["clips"] = len(test)
        res["families"][name]["frames"] = int(sum(len(c.joints) for c in test))
    res["seconds"] = time.perf_counter() - t0
    methods = ("input", "gauss", "savgol", "filter_before", "filter")
    for name, fams in res["families"].items():
        for fam, b in fams.items():
            if not isinstance(b, dict):
                continue
            r = b["ratio_vs_best_smoother"]
            print(f"[{name} / {fam}] gauss sigma {b['gauss_sigma_frames']} frames, savgol window {b['savgol_window']}; "
                  f"filter / best smoother: tmpjpe {r['tmpjpe_mm']:.2f}, limb {r['limb_mm']:.2f}")
            print("  " + f"{'method':14s}" + "".join(f"{k:>16s}" for k in FIGURES))
            here = [m for m in methods if m in b]
            for m in here:
                print("  " + f"{m:14s}" + "".join(f"{b[m]['all'][k]:16.2f}" for k in FIGURES))
            print("  tmpjpe / limb (mm) by motion type: " + "; ".join(
                f"{t} " + " ".join(f"{m}={b[m][t]['tmpjpe_mm']:.1f}/{b[m][t]['limb_mm']:.1f}" for m in here)
                for t in MOTION_TYPES))
    if args.json:
        print_summary(res)
    return 0


def run(args: argparse.Namespace) -> int:
    from trumans.refine.corrupt import CorruptionConfig, corrupt

    resolve_checkpoint(args)

    from trumans.refine.pipeline import HOIFilter, RefineOptions

    filt = HOIFilter.load(args.checkpoint, device=args.device)
    opts = RefineOptions(num_steps=args.steps, mode=args.mode, seed=args.seed, post=post_steps_config(args))
    if args.families:
        return run_families(args, filt, opts)
    data = args.data or filt.ckpt.data.get("path")
    if not data or not Path(data).is_dir():
        raise FileNotFoundError(f"the checkpoint's dataset {data!r} is not on this machine; pass --data DIR "
                                f"(a dataset with val and test splits, e.g. from `trumans data synth`)")
    args.data = data
    if args.clip < filt.window:
        raise ValueError(f"--clip must be >= the filter's window ({filt.window}), got {args.clip}")
    val_clean, _ = _clips(args.data, "val", args.clip, filt.fps, filt.categories, args.max_clips, args.seed)
    val_tr = corrupt(val_clean, filt.fps, np.random.default_rng(args.seed + 1), CorruptionConfig())
    sg = tune_savgol(list(zip(val_tr, val_clean)))
    test_clean, cats = _clips(args.data, "test", args.clip, filt.fps, filt.categories,
                              args.max_clips if not args.category else 10 ** 9, args.seed)
    if args.category:
        category_indices(args.category, filt.categories)  # unknown names: a clear error
        keep = np.array([c in args.category for c in cats])
        if not keep.any():
            raise ValueError(f"the test split has no {args.clip}-frame clip of {args.category}")
        test_clean, cats = test_clean[keep][:args.max_clips], [c for c, k in zip(cats, keep) if k][:args.max_clips]
    res = {"checkpoint": str(args.checkpoint or "models/refine.pt"), "data": str(Path(args.data)), "seed": args.seed,
           "categories": sorted(set(cats)),
           "sampling_steps": args.steps, "mode": args.mode, "savgol_window": sg, "device": str(args.device)}
    post = opts.post
    res["rest_pooling"], res["hand_link"], res["body_drift"] = post.rest_pooling.enabled, post.rest_pooling.hand_link, post.body_drift.enabled
    res["hinge"], res["foot_lock"] = post.hinge.enabled, post.foot_lock.enabled
    res["post_config"] = post.to_dict()
    res.update(evaluate(filt, test_clean, cats, CorruptionConfig(), sg, args.seed, opts, per_clip_speed=True,
                        rest_ablation=True))
    res["no_imu"] = evaluate(filt, test_clean, cats, CorruptionConfig().without_imu(), sg, args.seed, opts)
    res["drift"] = evaluate(filt, test_clean, cats, CorruptionConfig.drift(), sg, args.seed, opts)
    if args.real:
        res["real"] = evaluate_real(filt, args.clip, args.max_clips, sg, args.seed, opts)
    if args.ablation:
        abl = HOIFilter.load(args.ablation, device=args.device)
        res["ablation"] = {"checkpoint": args.ablation,
                           **evaluate(abl, test_clean, cats, CorruptionConfig(), sg, args.seed, opts)}
    keys = ("mpjpe_in_mm", "mpjpe_out_mm", "mpjpe_out_no_drift_mm", "mpjpe_out_drift_oracle_mm", "mpjpe_savgol_mm", "mpjpe_in_ra_mm", "mpjpe_out_ra_mm", "mpjpe_savgol_ra_mm", "accel_err_in", "accel_err_out", "accel_gt",
            "obj_t_err_in_cm", "obj_t_err_out_cm", "obj_t_err_out_no_rest_cm", "obj_rot_err_in_deg", "obj_rot_err_out_deg",
            "obj_rot_err_out_no_rest_deg", "frames_per_s")
    for name, block in [("default", res), ("no_imu", res["no_imu"]), ("drift", res["drift"])] + (
            [("ablation", res["ablation"])] if "ablation" in res else []) + (
            [("real", res["real"]["default"]), ("real_dr", res["real"]["drift"])] if "real" in res else []):
        print(f"{name:8s} " + "  ".join(f"{k}={block[k]:.1f}" for k in keys if k in block))
    if args.json:
        print_summary(res)
    return 0
