"""`trumans eval contacts [CHECKPOINT | DOF=CHECKPOINT ...]`: interaction-tracking figures (iReplica Tabs. 1-3).

On held-out synthetic sequences (by default a small set built here with a seed that training
never sees; or ``--data DIR --split test``) whose root is moved by a simulated localisation error:
a smooth offset of 5-15 cm whose direction and size drift with time and distance walked
(about a radian per 30 s or 4 m), plus
3 mm per-frame jitter. Figures (one JSON object with --json):
- ``ap``, ``precision``, ``recall``, ``accuracy``: per-hand, per-frame contact at threshold 0.5
  (labels: wrist or index1 in contact); ``*_interaction``: the same against the contacts made while
  a movable object is being moved (``labels.sequence_labels`` class not "none"; what one model per
  dof class is trained to detect, ``per_dof``);
- ``obj_center_err_cm``, ``obj_angle_err_deg``: tracked vs true pose of each moved object at the
  end of each of its true interactions (centre of its bounding box; rotation angle);
- ``hand_obj_dist_cm``: mean distance from the contacting hand's skin (nearest of wrist / index1
  minus its radius, >= 0) to the attached object during the tracked interactions (``_gt``: the
  same on the true motion during true interactions);
- the same object and distance figures without trajectory correction (``*_nocorr``);
- ``--real``: the same tracker on real motion (the corpus's handling clips with their fitted
  scenes and objects; figures in ``trumans.track.eval_real``);
- ``motion_min_per_s``: minutes of motion tracked per second of wall-clock time (prediction,
  correction and objects; after a warm-up run), and per second of this process's CPU time
  (``motion_min_per_cpu_s``: the same work on an unshared machine).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from trumans.summary import print_summary
from trumans import argtypes
from trumans.checkpoint_args import add_checkpoint_arguments, resolve_checkpoint
from trumans.common_args import add_device_argument

__all__ = ["add_arguments", "run", "simulate_drift", "evaluate"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_checkpoint_arguments(p, "contact checkpoint (default: the shipped models/contacts.pt, one model with a class "
                                "head), or DOF=CHECKPOINT for each dof class (slide, hinge, free) to evaluate one model "
                                "per class", many=True, metavar="[DOF=]CHECKPOINT")
    p.add_argument("--data", default=None, help="dataset folder (default: a held-out synthetic set built here)")
    p.add_argument("--split", default="test", help="split of --data (default test)")
    p.add_argument("--rooms", type=int, default=4, help="rooms of the held-out set built without --data (default 4)")
    p.add_argument("--max-seqs", type=int, default=12, help="at most this many sequences (default 12)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (held-out set, drift)")
    p.add_argument("--real", action="store_true",
                   help="evaluate on real motion instead: the corpus clips that pick up / carry / put down (or reach "
                        "down), placed with their fitted scenes and objects as the dataset's real takes "
                        "(trumans.track.eval_real); --max-seqs caps the clips, --seed seeds the rooms and the drift")
    p.add_argument("--real-split", choices=("test", "train"), default="test",
                   help="corpus split of --real (default test: the held-out subjects; train clips may be in the "
                        "contact model's training data)")
    p.add_argument("--stride", type=int, default=3, help="prediction stride (default 3; 1 = the centre frame of every window, as the paper)")
    add_device_argument(p, runs="the contact predictor(s); the tracker's correction and objects are numpy on the CPU")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on the last line")


def simulate_drift(root_xy: np.ndarray, fps: float, rng: np.random.Generator, lo: float = 0.05, hi: float = 0.15,
                   jitter: float = 0.003) -> np.ndarray:
    """A localisation error (T, 2) m for a root path (T, 2): magnitude in [lo, hi] and direction
    varying smoothly with u = time / 30 s + distance walked / 4 m, plus iid jitter (m)."""
    T = len(root_xy)
    walked = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(root_xy, axis=0), axis=1))]
    u = np.arange(T) / fps / 30.0 + walked / 4.0
    f, ph = rng.uniform(0.5, 1.5, 3), rng.uniform(0, 2 * np.pi, 3)
    mag = lo + (hi - lo) * 0.5 * (1 + np.sin(f[0] * u + ph[0]))
    ang = ph[1] + 1.5 * np.sin(f[1] * u + ph[2]) + f[2] * u
    return mag[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1) + rng.normal(0, jitter, (T, 2))


def _hand_surface_dist(queries, name: str, poses: np.ndarray, joints: np.ndarray, hand: int) -> np.ndarray:
    """Skin-to-object distance (n,) m of one hand (0 left, 1 right): joints (n, 24, 3), poses (n, 4, 4)."""
    from trumans.track.predictor import HAND_JOINTS, HANDS
    from trumans.contacts.rule import JOINT_RADIUS

    jj = list(HAND_JOINTS[HANDS[hand]])
    inv = np.linalg.inv(poses)
    local = np.einsum("nij,nkj->nki", inv[:, :3, :3], joints[:, jj]) + inv[:, None, :3, 3]
    d = queries.distance(name, local)  # (n, 2)
    return np.maximum(d - JOINT_RADIUS[jj], 0.0).min(1)


class _Dist:
    def __init__(self, scene) -> None:
        from trumans.scenes.distance import SceneDistance

        self.scene, self._sd, self.SD = scene, {}, SceneDistance

    def distance(self, name: str, local: np.ndarray) -> np.ndarray:
        if name not in self._sd:
            self._sd[name] = self.SD({name: self.scene.objects[name].mesh})
        return self._sd[name].query(local).dist.astype(np.float64)


def _pose_errors(pred: np.ndarray, gt: np.ndarray, center: np.ndarray) -> tuple[float, float]:
    """Centre distance (cm) and rotation angle (deg) between two (4, 4) poses of one object."""
    c_p, c_g = pred[:3, :3] @ center + pred[:3, 3], gt[:3, :3] @ center + gt[:3, 3]
    cos = np.clip((np.trace(pred[:3, :3].T @ gt[:3, :3]) - 1) / 2, -1, 1)
    return float(np.linalg.norm(c_p - c_g) * 100), float(np.degrees(np.arccos(cos)))


def evaluate(model, sequences: list, scenes: dict, seed: int = 0, stride: int = 3) -> dict:
    """Figures (module doc) over ``sequences`` (Sequence objects with contacts and true object
    tracks) in ``scenes`` (scene id -> Scene)."""
    from trumans.track.interactions import TrackerConfig, track
    from trumans.track.labels import hand_labels, moving_intervals, sequence_labels
    from trumans.track.scores import binary_scores
    from trumans.sequence import Sequence

    rng = np.random.default_rng([seed, 12])
    probs, labels, interaction_labels = [], [], []
    err = {"": ([], []), "_nocorr": ([], [])}
    by_dof: dict[str, list[float]] = {}
    dist = {"": [], "_nocorr": [], "_gt": []}
    minutes, seconds, cpu_seconds = 0.0, 0.0, 0.0
    track(sequences[0], scenes[sequences[0].scene], model)  # warm-up: one-time imports and allocations
    for seq in sequences:
        scene = scenes[seq.scene]
        queries = _Dist(scene)
        drift = simulate_drift(seq.joints[:, 0, :2].astype(np.float64), seq.fps, rng)
        joints = seq.joints.copy()
        joints[:, :, :2] += drift[:, None].astype(np.float32)
        root = None if seq.root_pos is None else seq.root_pos + np.c_[drift, np.zeros(len(drift))].astype(np.float32)
        noisy = Sequence(joints=joints, fps=seq.fps, rotations=seq.rotations, root_pos=root, scene=seq.scene)
        gt_hands = hand_labels(seq.contacts)
        _, gt_class = sequence_labels(seq, {n: o.dof for n, o in scene.objects.items()})
        for suffix, correct in (("", True), ("_nocorr", False)):
            t0, c0 = time.perf_counter(), time.process_time()
            res = track(noisy, scene, model, TrackerConfig(correct=correct, predict_stride=stride))
            if correct:
                seconds += time.perf_counter() - t0
                cpu_seconds += time.process_time() - c0
                minutes += seq.num_frames / seq.fps / 60.0
                probs.append(res.prob)
                labels.append(gt_hands)
                interaction_labels.append(gt_hands & (gt_class > 0)[:, None])
            out = res.sequence
            for name, gt in seq.objects.items():
                if name not in out.objects:
                    continue
                center = scene.objects[name].mesh.bounds.mean(0)
                for s, e in moving_intervals(gt.pose):
                    c, a = _pose_errors(out.objects[name].pose[e - 1].astype(np.float64), gt.pose[e - 1].astype(np.float64), center)
                    err[suffix][0].append(c)
                    err[suffix][1].append(a)
                    if correct:
                        by_dof.setdefault(scene.objects[name].dof, []).append(c)
            for it in res.interactions:
                for seg in it.segments:
                    for h in (0, 1):
                        if seg.hands[h]:
                            sl = slice(seg.start, seg.end)
                            dist[suffix].append(_hand_surface_dist(queries, it.name, out.objects[it.name].pose[sl].astype(np.float64),
                                                                   out.joints[sl].astype(np.float64), h))
        for name, gt in seq.objects.items():  # reference: the true motion during true interactions
            if scene.objects[name].dof == "static":
                continue
            for s, e in moving_intervals(gt.pose):
                for h in (0, 1):
                    fr = np.arange(s, e)[gt_hands[s:e, h]]
                    if len(fr):
                        d = _hand_surface_dist(queries, name, gt.pose[fr].astype(np.float64), seq.joints[fr].astype(np.float64), h)
                        dist["_gt"].append(d[d < 0.1])  # the hand holding this object, not another one
    fig = binary_scores(np.concatenate(probs), np.concatenate(labels)) if probs else {}
    if probs:
        inter = binary_scores(np.concatenate(probs), np.concatenate(interaction_labels))
        fig.update({f"{k}_interaction": v for k, v in inter.items()})
    mean = lambda xs: float(np.mean(xs)) if len(xs) else float("nan")
    for suffix in ("", "_nocorr"):
        fig[f"obj_center_err_cm{suffix}"] = mean(err[suffix][0])
        fig[f"obj_angle_err_deg{suffix}"] = mean(err[suffix][1])
    for suffix in ("", "_nocorr", "_gt"):
        fig[f"hand_obj_dist_cm{suffix}"] = mean(np.concatenate(dist[suffix]) * 100) if dist[suffix] else float("nan")
    fig["motion_min_per_s"] = minutes / max(seconds, 1e-9)
    fig["motion_min_per_cpu_s"] = minutes / max(cpu_seconds, 1e-9)
    fig["obj_center_err_cm_by_dof"] = {k: float(np.mean(v)) for k, v in sorted(by_dof.items())}
    fig["interactions_by_dof"] = {k: len(v) for k, v in sorted(by_dof.items())}
    fig["sequences"] = len(sequences)
    fig["object_interactions"] = len(err[""][0])
    fig["motion_min"] = minutes
    return fig


def run(args: argparse.Namespace) -> int:
    from trumans.track.model_io import load_contact_models
    from trumans.dataset import Dataset

    if args.max_seqs < 1 or args.rooms < 1:
        raise ValueError(f"--max-seqs and --rooms must be >= 1, got {args.max_seqs}, {args.rooms}")
    if args.stride < 1 or args.stride % 2 == 0:
        raise ValueError(f"--stride must be an odd number >= 1, got {args.stride}")
    if args.real and args.data is not None:
        raise ValueError("--real evaluates the corpus's real clips; give --real or --data, not both")
    model = load_contact_models(resolve_checkpoint(args), device=args.device)
    if args.real:
        from trumans.track.eval_real import run_real

        return run_real(model, args)
    with tempfile.TemporaryDirectory(prefix="trumans_eval_contacts_") as tmp:
        if args.data is None:
            from trumans.synth.build import SynthConfig, build_dataset

            minutes_per_room = 1.5
            build_dataset(SynthConfig(out=tmp, hours=args.rooms * minutes_per_room / 60, rooms=args.rooms,
                                      seed=10_000 + args.seed, workers=1, take_seconds=(30.0, 60.0)), progress=False)
            ds = Dataset(tmp)
            files = ds.files
        else:
            ds = Dataset(args.data)
            files = ds.split(args.split)
        seqs = [s for s in (ds.load(f) for f in files[: args.max_seqs]) if s.rotations is not None and s.contacts is not None]
        if not seqs:
            raise ValueError(f"no sequence with rotations and contacts in {ds.root}; evaluate on a labelled dataset")
        scenes = {sid: ds.scene(sid) for sid in sorted({s.scene for s in seqs})}
        fig = evaluate(model, seqs, scenes, args.seed, args.stride)
    fig["checkpoint"] = " ".join(args.checkpoint) or "models/contacts.pt (shipped)"
    fig["device"] = str(args.device)
    keys = ["ap", "precision", "recall", "accuracy", "ap_interaction", "precision_interaction", "recall_interaction",
            "obj_center_err_cm", "obj_angle_err_deg", "hand_obj_dist_cm",
            "obj_center_err_cm_nocorr", "obj_angle_err_deg_nocorr", "hand_obj_dist_cm_nocorr", "hand_obj_dist_cm_gt",
            "motion_min_per_s", "motion_min_per_cpu_s"]
    for k in keys:
        print(f"{k:26s} {fig[k]:.3f}")
    print("object centre error by dof (cm): " + ", ".join(f"{k} {v:.2f} ({fig['interactions_by_dof'][k]})"
                                                          for k, v in fig["obj_center_err_cm_by_dof"].items()))
    print(f"{fig['sequences']} sequences, {fig['motion_min']:.1f} min of motion, {fig['object_interactions']} object interactions")
    if args.json:
        print_summary(fig)
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m trumans.track.evaluate", description=__doc__.splitlines()[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
