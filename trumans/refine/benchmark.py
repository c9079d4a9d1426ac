"""The body benchmark of the HOI filter: per corruption family and per motion type, beside tuned
classical smoothers (``trumans eval refine --families``).

Clips (body only; the object is a still placeholder):

- real: the mocap corpus's held-out test subjects, whole clips (``trumans.mocap_corpus``); the
  smoothers are tuned on a seeded sample of the corpus's train clips (the corpus has no val split;
  the filter's fitted skip saw the train split, the tuned parameters are the smoothers' only);
- synthetic (with ``--data``): the dataset's test sequences, smoothers tuned on its val split.

Families: ``clean`` (no corruption: does the filter leave clean motion alone?), ``default`` (the training corruption, ``trumans.refine.corrupt.CorruptionConfig``, without
an IMU), ``tracker`` (the independent tracker model, ``trumans.refine.tracker_noise``, every kind
together) and, with ``kinds``, ``tracker.<kind>`` for each tracker kind alone.

Figures per clip, averaged over clips (per motion type: over that type's frames):

- ``mpjpe_mm``: the mean joint error as it is (for the ``clean`` family: how far the output moved
  the clean input);
- ``tmpjpe_mm``: translation-aligned MPJPE: the output moved by the one translation (over the whole
  clip) that best aligns it with the truth, then the mean joint error (a constant drift, which no
  estimate from the sequence alone can see, does not count; a drift's changes do);
- ``limb_mm``: the limbs' error from their roots: knee, ankle and toe base relative to their hip,
  elbow, wrist and index1 relative to their shoulder (the pose of the limbs, whatever the trunk does);
- ``accel_mm``: mean |second difference - the truth's| of the joints, mm/frame^2;
- ``skate_cm_s``: the mean horizontal speed of the foot joints (ankles, toe bases) on the frames
  where the truth's is planted (under 5 cm/s and within 5 cm of its lowest), cm/s (the truth's own:
  the ``input`` row of the ``clean`` family);
- ``under_floor``: frames with a foot joint under z = 0 (a count over the clips) and
  ``under_floor_pct`` (their share, %);
- ``ra_mpjpe_mm``: root-aligned MPJPE (each frame's pelvis put on the truth's), the old column;
- ``bone_dev_pct``: the largest |output / truth - 1| over the bones of a clip's median bone lengths
  (bones of 2 cm or more in the truth), %.

Clip sets: ``real``, ``foreign`` (``foreign_skeleton``: the real test clips with 0.85x legs and a
1.15x spine, to check that the output keeps the input's proportions) and ``synthetic``.

Methods: ``input`` (the tracked joints, gaps linearly filled), ``gauss`` (Gaussian low-pass, sigma
tuned), ``savgol`` (Savitzky-Golay order 2, window tuned), ``filter`` (the full pipeline) and
``filter_before`` (the same network and post-steps with the input guards of issue 36 off: no gate,
input bones, floor, held joints or leg swaps).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import savgol_filter

from trumans.skeleton import FOOT_JOINTS, JOINT_INDEX, NUM_JOINTS, PARENTS, SPINE

from trumans.motion_labels import MOTION_TYPES, motion_types
from trumans.refine.frame import fill_missing_joints

__all__ = ["MOTION_TYPES", "BodyClip", "FIGURES", "translation_aligned_errors", "limb_errors", "clip_errors",
           "gauss_smooth", "savgol_smooth", "tune_smoother", "motion_types", "real_body_clips", "synthetic_body_clips",
           "corrupt_family", "family_names", "benchmark"]

FIGURES: tuple[str, ...] = ("mpjpe_mm", "tmpjpe_mm", "limb_mm", "accel_mm", "skate_cm_s", "under_floor", "under_floor_pct",
                            "ra_mpjpe_mm", "bone_dev_pct")
GAUSS_SIGMAS = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0)
SAVGOL_WINDOWS = (5, 7, 9, 11, 13, 15, 17, 21, 25, 31)
_LIMB_ROOT = {JOINT_INDEX[f"{s}_{n}"]: JOINT_INDEX[f"{s}_{r}"] for s in ("left", "right")
              for r, names in (("hip", ("knee", "ankle", "foot")), ("shoulder", ("elbow", "wrist", "index1")))
              for n in names}
_LIMBS = np.array(list(_LIMB_ROOT))
_ROOTS = np.array(list(_LIMB_ROOT.values()))
_FEET = list(FOOT_JOINTS)


@dataclass
class BodyClip:
    """A clean clip: joints (T, 24, 3) m z-up at ``fps``, per-frame motion types (T, len(MOTION_TYPES))
    bool, and its name."""

    name: str
    joints: np.ndarray
    fps: float
    types: np.ndarray


def _check_pair(J: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    J, G = np.asarray(J, np.float64), np.asarray(G, np.float64)
    if J.shape != G.shape or J.ndim != 3 or J.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"output and truth must both be (T, 24, 3), got {J.shape} and {G.shape}")
    return J, G


def translation_aligned_errors(J: np.ndarray, G: np.ndarray) -> np.ndarray:
    """(T, 24) m: |J + c - G| with c the clip's mean of G - J (the least-squares translation)."""
    J, G = _check_pair(J, G)
    return np.linalg.norm(J + (G - J).reshape(-1, 3).mean(0) - G, axis=-1)


def limb_errors(J: np.ndarray, G: np.ndarray) -> np.ndarray:
    """(T, 12) m: the limb joints' errors relative to their limb roots (legs from the hip, arms from
    the shoulder)."""
    J, G = _check_pair(J, G)
    return np.linalg.norm((J[:, _LIMBS] - J[:, _ROOTS]) - (G[:, _LIMBS] - G[:, _ROOTS]), axis=-1)


def _planted(G: np.ndarray, fps: float) -> np.ndarray:
    F = G[:, _FEET]
    v = np.r_[np.zeros((1, len(_FEET))), np.linalg.norm(np.diff(F, axis=0), axis=-1) * fps]
    return (v < 0.05) & (F[..., 2] < F[..., 2].min(0) + 0.05)


def clip_errors(J: np.ndarray, G: np.ndarray, fps: float) -> dict[str, np.ndarray]:
    """Per-frame figures of output J vs truth G (T, 24, 3) m: ``tmpjpe`` (T,) m, ``limb`` (T,) m,
    ``accel`` (T,) m/frame^2 (the end frames: NaN), ``skate`` (T,) m/s (NaN where no foot is
    planted), ``under`` (T,) bool, ``ra`` (T,) m."""
    J, G = _check_pair(J, G)
    T = len(J)
    acc = np.full(T, np.nan)
    if T >= 3:
        acc[1:-1] = np.linalg.norm(np.diff(J, 2, axis=0) - np.diff(G, 2, axis=0), axis=-1).mean(-1)
    planted = _planted(G, fps)
    speed = np.r_[np.zeros((1, len(_FEET))), np.linalg.norm(np.diff(J[:, _FEET, :2], axis=0), axis=-1) * fps]
    n = planted.sum(1)
    skate = np.where(n > 0, (speed * planted).sum(1) / np.maximum(n, 1), np.nan)
    med = lambda X: np.median(np.linalg.norm(X[:, 1:] - X[:, PARENTS[1:]], axis=-1), axis=0)
    lg, lj = med(G), med(J)
    dev = 100 * float(np.abs(lj[lg >= 0.02] / lg[lg >= 0.02] - 1).max()) if (lg >= 0.02).any() else float("nan")
    return {"bone_dev": np.full(T, dev), "mpjpe": np.linalg.norm(J - G, axis=-1).mean(-1), "tmpjpe": translation_aligned_errors(J, G).mean(-1), "limb": limb_errors(J, G).mean(-1), "accel": acc,
            "skate": skate, "under": (J[:, _FEET, 2] < 0).any(-1),
            "ra": np.linalg.norm((J - J[:, :1]) - (G - G[:, :1]), axis=-1).mean(-1)}


def _summary(rows: list[dict[str, np.ndarray]], masks: list[np.ndarray] | None = None) -> dict[str, float]:
    """Means over clips of per-clip means (over ``masks``' frames when given; clips without any skipped)."""
    out: dict[str, list[float]] = {k: [] for k in FIGURES}
    count = 0
    for i, r in enumerate(rows):
        m = np.ones(len(r["tmpjpe"]), bool) if masks is None else masks[i]
        if not m.any():
            continue
        count += 1
        for k, scale in (("mpjpe", 1000), ("tmpjpe", 1000), ("limb", 1000), ("accel", 1000), ("ra", 1000),
                         ("skate", 100), ("bone_dev", 1)):
            v = r[k][m]
            v = v[np.isfinite(v)]
            if len(v):
                out[{"mpjpe": "mpjpe_mm", "tmpjpe": "tmpjpe_mm", "limb": "limb_mm", "accel": "accel_mm", "ra": "ra_mpjpe_mm",
                     "skate": "skate_cm_s", "bone_dev": "bone_dev_pct"}[k]].append(scale * float(v.mean()))
        out["under_floor"].append(float(r["under"][m].sum()))
        out["under_floor_pct"].append(100.0 * float(r["under"][m].mean()))
    res = {k: (float(np.sum(v)) if k == "under_floor" else float(np.mean(v))) if v else float("nan")
           for k, v in out.items()}
    res["clips"] = count
    return res


def gauss_smooth(tracked: np.ndarray, sigma: float) -> np.ndarray:
    """Tracked joints (T, 24, 3) m (NaN = missing, linearly filled first) -> Gaussian low-pass in
    time, sigma in frames (edges: nearest)."""
    return gaussian_filter1d(fill_missing_joints(tracked), sigma, axis=0, mode="nearest")


def savgol_smooth(tracked: np.ndarray, window: int) -> np.ndarray:
    """Tracked joints (T, 24, 3) m (NaN = missing, linearly filled first) -> Savitzky-Golay, order 2,
    ``window`` frames (odd; shortened to the clip)."""
    X = fill_missing_joints(tracked)
    w = min(int(window), len(X) - (1 - len(X) % 2))
    return savgol_filter(X, w, 2, axis=0) if w > 2 else X


def tune_smoother(kind: str, pairs: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """The parameter of ``kind`` ('gauss': sigma, 'savgol': window) with the least mean
    translation-aligned MPJPE over (tracked, clean) joint pairs."""
    smooth, grid = {"gauss": (gauss_smooth, GAUSS_SIGMAS), "savgol": (savgol_smooth, SAVGOL_WINDOWS)}[kind]
    err = {p: np.mean([translation_aligned_errors(smooth(tr, p), cl).mean() for tr, cl in pairs]) for p in grid}
    return min(err, key=err.get)


def real_body_clips(split: str, max_clips: int | None = None, seed: int = 0) -> list[BodyClip]:
    """Corpus clips of ``split`` ('test': the held-out subjects; 'train': the tuning sample), whole,
    at their 30 fps; at most ``max_clips`` (a seeded sample)."""
    from trumans.mocap_corpus import load_corpus

    clips = load_corpus(split=split)
    if max_clips is not None and len(clips) > max_clips:
        idx = np.sort(np.random.default_rng(seed).choice(len(clips), max_clips, replace=False))
        clips = [clips[i] for i in idx]
    return [BodyClip(c.name, c.joints.astype(np.float64), c.fps,
                     motion_types(c.joints, c.fps, np.full(len(c.joints), "pick" in c.description.lower())))
            for c in clips]


def foreign_skeleton(clips: list[BodyClip], legs: float = 0.85, spine: float = 1.15) -> list[BodyClip]:
    """The clips with other proportions: every leg bone (hip to knee, knee to ankle, ankle to toe
    base) ``legs`` times as long, every spine bone (pelvis to spine1 up to spine3) ``spine`` times,
    each joint placed root first at its parent plus the clip's own bone direction, the feet put back
    on the floor (the lowest foot joint's 5th percentile kept)."""
    from trumans.refine.bones import project_bone_lengths

    scale = np.ones(NUM_JOINTS)
    scale[[JOINT_INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("knee", "ankle", "foot")]] = legs
    scale[list(SPINE)] = spine
    out = []
    for c in clips:
        L = np.median(np.linalg.norm(c.joints[:, 1:] - c.joints[:, PARENTS[1:]], axis=-1), axis=0)
        J = project_bone_lengths(c.joints, np.r_[0.0, L] * scale, rounds=0)
        feet = lambda X: np.percentile(X[:, _FEET, 2].min(1), 5)
        J[..., 2] += feet(c.joints) - feet(J)
        out.append(BodyClip(c.name + "_foreign", J, c.fps, c.types))
    return out


def synthetic_body_clips(data: str, split: str, fps: float, max_frames: int = 3000) -> list[BodyClip]:
    """A dataset's ``split`` sequences at ``fps``, cut into pieces of at most ``max_frames``; pick_up
    from the action labels ``pick_up``."""
    from trumans.dataset import Dataset
    from trumans.resample import resample_sequence

    ds = Dataset(data)
    out = []
    for path in ds.split(split):
        seq = resample_sequence(ds.load(path), fps)
        pick = np.zeros(seq.num_frames, bool)
        if seq.actions is not None and seq.action_names is not None and "pick_up" in list(seq.action_names):
            pick = np.asarray(seq.actions)[:, list(seq.action_names).index("pick_up")] > 0
        for s in range(0, seq.num_frames, max_frames):
            J = np.asarray(seq.joints[s:s + max_frames], np.float64)
            if len(J) >= 64:
                out.append(BodyClip(f"{path}:{s}", J, fps, motion_types(J, fps, pick[s:s + max_frames])))
    if not out:
        raise ValueError(f"split {split!r} of {data} has no sequence of 64 frames or more")
    return out


def family_names(kinds: bool) -> list[str]:
    """'clean', 'default', 'tracker' and, with ``kinds``, 'tracker.<kind>' for each tracker kind."""
    from trumans.refine.tracker_noise import TRACKER_KINDS

    return ["clean", "default", "tracker"] + ([f"tracker.{k}" for k in TRACKER_KINDS] if kinds else [])


def corrupt_family(family: str, clips: list[BodyClip], seed: int) -> list[np.ndarray]:
    """Tracked joints (T, 24, 3) per clip (NaN = missing) under ``family`` (``family_names``)."""
    from trumans.refine.corrupt import CorruptionConfig, corrupt
    from trumans.refine.frame import JOINTS, pack_frames
    from trumans.refine.tracker_noise import TrackerConfig, tracker_corrupt

    rng = np.random.default_rng(seed)
    out = []
    for c in clips:
        if family == "clean":
            out.append(np.array(c.joints, np.float64))
        elif family == "default":
            fr = pack_frames(c.joints, None, np.broadcast_to(np.eye(4), (len(c.joints), 4, 4)))
            tr = corrupt(fr[None], c.fps, rng, CorruptionConfig().without_imu())[0]
            out.append(tr[:, JOINTS].reshape(-1, NUM_JOINTS, 3).astype(np.float64))
        elif family == "tracker" or family.startswith("tracker."):
            cfg = TrackerConfig() if family == "tracker" else TrackerConfig().only(family.split(".", 1)[1])
            out.append(tracker_corrupt(c.joints[None], c.fps, rng, cfg)[0].astype(np.float64))
        else:
            raise ValueError(f"unknown corruption family {family!r}; the families: {family_names(True)}")
    return out


def _refine(filt, tracked: list[np.ndarray], fps: list[float], options) -> list[np.ndarray]:
    from trumans.refine.frame import JOINTS, pack_frames

    frames = [pack_frames(np.nan_to_num(t, nan=0.0), None, np.broadcast_to(np.eye(4), (len(t), 4, 4))) for t in tracked]
    for f, t in zip(frames, tracked):  # NaN joints stay missing
        f[:, JOINTS] = t.reshape(len(t), -1)
    outs = filt.refine_many(frames, fps, [filt.categories[0]] * len(frames), options)
    return [o[:, JOINTS].reshape(-1, NUM_JOINTS, 3).astype(np.float64) for o in outs]


def before_options(options):
    """``options`` with issue 36's input guards off (gate, input bones, floor, held joints, leg swaps)."""
    return replace(options, held_joints=False, leg_swaps=False,
                   post=options.post.switched(gate=False, bones=False, floor=False))


def benchmark(filt, test: list[BodyClip], val: list[BodyClip], families: list[str], seed: int, options,
              before: tuple[str, ...] = ("clean", "default", "tracker")) -> dict:
    """Per family: the tuned smoothers' parameters and, per method, ``all`` and per motion type
    figures (``FIGURES``), plus ``ratio_vs_best_smoother`` (the filter's tmpjpe / limb over the better
    of the two smoothers on each). ``before``: the families that also get ``filter_before``."""
    res: dict = {}
    for fi, fam in enumerate(families):
        val_tr = corrupt_family(fam, val, seed + 1000 + fi)
        pairs = [(t, c.joints) for t, c in zip(val_tr, val)]
        sigma, window = tune_smoother("gauss", pairs), tune_smoother("savgol", pairs)
        tr = corrupt_family(fam, test, seed + fi)
        outs = {"input": [fill_missing_joints(t) for t in tr], "gauss": [gauss_smooth(t, sigma) for t in tr],
                "savgol": [savgol_smooth(t, window) for t in tr],
                "filter": _refine(filt, tr, [c.fps for c in test], options)}
        if fam in before:
            outs["filter_before"] = _refine(filt, tr, [c.fps for c in test], before_options(options))
        block: dict = {"gauss_sigma_frames": sigma, "savgol_window": window}
        for name, Js in outs.items():
            rows = [clip_errors(J, c.joints, c.fps) for J, c in zip(Js, test)]
            block[name] = {"all": _summary(rows)}
            for ti, t in enumerate(MOTION_TYPES):
                block[name][t] = _summary(rows, [c.types[:, ti] for c in test])
        best = {k: min(block["gauss"]["all"][k], block["savgol"]["all"][k]) for k in ("tmpjpe_mm", "limb_mm")}
        block["ratio_vs_best_smoother"] = {k: block["filter"]["all"][k] / best[k] for k in best}
        res[fam] = block
    return res
