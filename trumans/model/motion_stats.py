"""Statistics of a training set that a sampler needs to drive the generator like the data moved.

Stored in a generator checkpoint's ``meta`` (``sampling_stats``): the walking speed (so subgoals
are spaced like the training episodes' displacement), the typical duration of each action (so
the progress indicator runs at the data's pace), and a standing start pose (canonical frame:
pelvis at x = y = 0, facing +x): the standing frame nearest the coordinate-wise median of all of
them, a real body. (The median itself is not one: averaging arms that hang, swing and fold
shortens them, its forearms were 13 % shorter than any body's in the default data.) Every distinct
body (bone lengths to the centimetre) counts the same: in the default data 152 real takes share a
few CMU skeletons, so frames weighted by take made the start body a CMU one, whose proportions
(long legs, short trunk) the shipped generator does not keep: it drew its legs 5 % shorter, the
projection onto the body's bones put the feet under the floor and the foot cleanup bent the knees
(docs/sampling_log.md, "The start body").
"""
from __future__ import annotations

import numpy as np

from trumans.actions import remap_labels
from trumans.intervals import runs
from trumans.resample import resample_sequence
from trumans.skeleton import JOINT_INDEX, bone_lengths, heading

__all__ = ["sampling_stats", "standing_pose", "canonical_pose"]

_PELVIS = JOINT_INDEX["pelvis"]
PER_BODY = 20  # standing frames per distinct body for the start pose (module doc)


def canonical_pose(joints: np.ndarray) -> np.ndarray:
    """(N, 24, 3) world -> (N, 24, 3) each frame with its pelvis at x = y = 0, facing +x."""
    yaw = heading(joints)
    c, s = np.cos(-yaw), np.sin(-yaw)
    d = joints.astype(np.float64).copy()
    d[..., :2] -= d[:, None, _PELVIS, :2]
    x, y = d[..., 0].copy(), d[..., 1].copy()
    d[..., 0] = c[:, None] * x - s[:, None] * y
    d[..., 1] = s[:, None] * x + c[:, None] * y
    return d


def standing_pose(frames: np.ndarray, per_body: int | None = None, seed: int = 0) -> np.ndarray:
    """Standing frames (N, 24, 3) world -> (24, 3) canonical: the frame nearest (mean joint
    distance, canonical frames) to the coordinate-wise median of all of them (module doc).
    per_body: first keep at most this many frames (seeded draw) of each distinct body (bone
    lengths rounded to 1 cm), so that every body weighs the same."""
    f = np.asarray(frames, dtype=np.float64)
    if f.ndim != 3 or f.shape[1:] != (24, 3) or len(f) == 0:
        raise ValueError(f"standing frames must be (N, 24, 3) with N >= 1, got {f.shape}")
    if per_body is not None:
        if per_body < 1:
            raise ValueError(f"per_body must be >= 1, got {per_body}")
        _, body = np.unique(np.round(bone_lengths(f), 2), axis=0, return_inverse=True)
        rng = np.random.default_rng(seed)
        keep = [rng.permutation(np.flatnonzero(body.ravel() == b))[:per_body] for b in np.unique(body)]
        f = f[np.sort(np.concatenate(keep))]
    can = canonical_pose(f)
    median = np.median(can, axis=0)
    return can[int(np.argmin(np.linalg.norm(can - median, axis=-1).mean(-1)))]


def sampling_stats(dataset, split: str, vocabulary: list[str], fps: float, max_sequences: int = 200,
                   real_takes: bool = False) -> dict:
    """{"walk_speed": m/s, "action_seconds": {name: s}, "start_pose": (24, 3) list} from ``split``.

    dataset: ``trumans.dataset.Dataset``; sequences are resampled to ``fps`` first; at most
    ``max_sequences`` of them, spread evenly over the split. real_takes: also use the takes the index
    lists under "real" (mocap placed in fitted rooms). Off by default: their actions are labelled
    from the motion, in fragments (the 4-h corpus' median sit run is 0.75 s, sit-down 0.1 s), and
    the planner would time a whole sit by them."""
    speeds, durations, stand = [], {a: [] for a in vocabulary}, []
    real = set() if real_takes else set(dataset.index.get("real", {}))
    files = [f for f in dataset.index["splits"].get(split, []) if f not in real]
    if not files:
        raise ValueError(f"split {split!r} has no {'' if real_takes else 'non-real '}sequences to take sampling "
                         f"statistics from")
    if len(files) > max_sequences:
        files = [files[i] for i in np.linspace(0, len(files) - 1, max_sequences).round().astype(int)]
    for rel in files:
        seq = resample_sequence(dataset.load(rel), fps)
        if seq.actions is None or seq.num_frames < 3:
            continue
        lab = remap_labels(np.asarray(seq.actions, np.float32), seq.action_names, vocabulary) > 0
        v = np.linalg.norm(np.diff(seq.joints[:, _PELVIS, :2], axis=0), axis=1) * fps
        for i, a in enumerate(vocabulary):
            for s, e in runs(lab[:, i], max_gap=0, min_len=1):
                durations[a].append((e - s) / fps)
        if "walk" in vocabulary:
            w = lab[1:, vocabulary.index("walk")]
            speeds.append(v[w])
        if "stand" in vocabulary:
            only = lab[:, vocabulary.index("stand")] & (lab.sum(1) == 1)
            stand.append(seq.joints[only][::5])
    speed = float(np.median(np.concatenate(speeds))) if speeds and sum(map(len, speeds)) else 1.0
    pose_src = np.concatenate(stand) if stand and sum(map(len, stand)) else None
    pose = standing_pose(pose_src, per_body=PER_BODY) if pose_src is not None and len(pose_src) else None
    out = {"walk_speed": round(speed, 4),
           "action_seconds": {a: round(float(np.median(d)), 3) for a, d in durations.items() if d}}
    if pose is not None:
        out["start_pose"] = np.round(pose, 5).tolist()
    return out
