"""Windows for training and evaluating the HOI filter: clean human-object frame vectors cut from a dataset's
sequences (the embedded HOI sequences), corrupted on the fly.

Each sequence of a split is resampled to the filter's fps and cut into windows of ``window``
frames every ``stride`` frames. A window's object is the one that moves most in it (translation
span + 0.5 m per radian of rotation); where nothing moves (< 2 cm), the one nearest to a wrist.
Human frames (T, 216) are stored once per sequence, object frames (T, 19: pose 9 + clean IMU 10,
eq. 16 over the whole sequence) once per (sequence, object), and a window is three integers, so
the data fits in memory at any size the machine can load. ``batch`` assembles the clean world
windows (B, L, 235) and the subjects' rest offsets (B, 24, 3) (for L_consist).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from trumans.dataset import Dataset
from trumans.refine.corrupt import add_clean_imu
from trumans.refine.frame import FRAME_DIM, IMU_FLAG, OBJ_T, ROTATIONS, pack_frames
from trumans.ik.fit import offsets_from_joints
from trumans.motion_labels import MOTION_TYPES, motion_types
from trumans.resample import resample_sequence
from trumans.rotations import matrix_to_6d, sixd_to_matrix
from trumans.sequence import Sequence
from trumans.skeleton import WRISTS

__all__ = ["FilterWindows", "load_filter_windows", "window_motion_types", "window_objects"]

_WRISTS = list(WRISTS)
_BODY_TYPES = MOTION_TYPES[:4]  # walk, sit, lie, get_up: read from the body itself
_MOVE_MIN_M = 0.02
_M_PER_RAD = 0.5


@dataclass
class FilterWindows:
    """human: list of (T_s, 216) float32; objects: list of (T_s, 19) float32 (object part of the
    frame vector, OBJ_T .. IMU_FLAG); offsets: (S, 24, 3); windows: (N, 3) int64 (sequence, start,
    object row); categories: (N,) int64 into ``category_names``; files: sequence paths."""

    human: list[np.ndarray]
    objects: list[np.ndarray]
    offsets: np.ndarray
    windows: np.ndarray
    categories: np.ndarray
    category_names: list[str]
    files: list[str]
    window: int
    fps: float

    def __len__(self) -> int:
        return len(self.windows)

    def only(self, names: Sequence[str]) -> "FilterWindows":
        """The windows whose object category is one of ``names`` (the vocabulary is kept)."""
        bad = sorted(set(names) - set(self.category_names))
        if bad:
            raise ValueError(f"object category {bad[0]!r} is not in this data's vocabulary {self.category_names}")
        keep = np.isin(self.categories, [self.category_names.index(n) for n in names])
        if not keep.any():
            raise ValueError(f"no window of category {sorted(names)} in this split; choose categories it has")
        return replace(self, windows=self.windows[keep], categories=self.categories[keep])

    def batch(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(clean world windows (B, L, 235) float32, offsets (B, 24, 3), categories (B,))."""
        w = self.windows[np.asarray(idx)]
        L = self.window
        out = np.empty((len(w), L, FRAME_DIM), dtype=np.float32)
        for b, (s, start, o) in enumerate(w):  # one slice copy per window
            out[b, :, :ROTATIONS.stop] = self.human[s][start:start + L]
            out[b, :, OBJ_T.start:] = self.objects[o][start:start + L]
        return out, self.offsets[w[:, 0]], self.categories[np.asarray(idx)]


def window_objects(seq: Sequence, starts: np.ndarray, length: int) -> list[str]:
    """The interacting object of each window [s, s + length): most motion, else nearest to a wrist."""
    names = list(seq.objects)
    P = np.stack([np.asarray(seq.objects[n].pose, np.float64) for n in names])  # (K, T, 4, 4)
    idx = starts[:, None] + np.arange(length)[None]  # (N, L)
    t = P[:, :, :3, 3][:, idx]  # (K, N, L, 3)
    span = np.linalg.norm(t.max(2) - t.min(2), axis=-1)  # (K, N)
    Rs = P[:, :, :3, :3]
    R0 = Rs[:, starts]  # (K, N, 3, 3)
    cosang = (np.einsum("knij,knlij->knl", R0, Rs[:, idx]) - 1) / 2  # trace(R0^T R) = 1 + 2 cos
    ang = np.arccos(np.clip(cosang, -1, 1)).max(-1)
    motion = span + _M_PER_RAD * ang
    wr = seq.joints[idx][:, :, _WRISTS]  # (N, L, 2, 3)
    dist = np.linalg.norm(t[:, :, :, None] - wr[None], axis=-1).min((-1, -2))  # (K, N)
    pick = np.where(motion.max(0) >= _MOVE_MIN_M, motion.argmax(0), dist.argmin(0))
    return [names[k] for k in pick]


def window_motion_types(data: FilterWindows, min_frames: int = 8) -> np.ndarray:
    """(N, 4) bool: whether each window holds at least ``min_frames`` frames of each body motion type
    (walk, sit, lie, get_up: ``MOTION_TYPES[:4]``; ``trumans.motion_labels.motion_types`` on each
    sequence's whole joints, so a window's labels see the motion around it)."""
    per_seq = [motion_types(h[:, :72].reshape(len(h), 24, 3).astype(np.float64), data.fps)[:, :len(_BODY_TYPES)]
               for h in data.human]
    out = np.zeros((len(data.windows), len(_BODY_TYPES)), bool)
    for s_idx, t in enumerate(per_seq):
        rows = np.flatnonzero(data.windows[:, 0] == s_idx)
        if not len(rows):
            continue
        c = np.concatenate([np.zeros((1, len(_BODY_TYPES)), np.int64), np.cumsum(t, 0)])  # (T + 1, 4)
        st = data.windows[rows, 1]
        out[rows] = (c[st + data.window] - c[st]) >= min_frames
    return out


def load_filter_windows(data_dir: str, split: str, window: int, stride: int, fps: float,
                        categories: list[str] | None = None) -> FilterWindows:
    """Windows of one split. categories: the category vocabulary to use (a window of another
    category is dropped); None = every category found, sorted."""
    ds = Dataset(data_dir)
    human, objects, offsets, rows, cats, files = [], [], [], [], [], []
    obj_row: dict[tuple[int, str], int] = {}
    for path in ds.split(split):
        seq = resample_sequence(ds.load(path), fps)
        if not seq.objects or seq.num_frames < window:
            continue
        s = len(human)
        if seq.rotations is None:
            continue  # the filter learns rotations: sequences without them are skipped
        rot = seq.rotations
        human.append(np.concatenate([seq.joints.reshape(seq.num_frames, -1),
                                     matrix_to_6d(sixd_to_matrix(np.asarray(rot, np.float64))).reshape(seq.num_frames, -1)],
                                    -1).astype(np.float32))
        offsets.append(np.asarray(seq.extra["offsets"], np.float32) if "offsets" in seq.extra
                       else offsets_from_joints(seq.joints).astype(np.float32))
        files.append(str(path))
        starts = np.arange(0, seq.num_frames - window + 1, stride)
        for start, name in zip(starts, window_objects(seq, starts, window)):
            if (s, name) not in obj_row:
                ob = seq.objects[name]
                f = add_clean_imu(pack_frames(seq.joints, None, ob.pose)[None], fps)[0]
                obj_row[(s, name)] = len(objects)
                objects.append(f[:, OBJ_T.start:IMU_FLAG + 1].copy())
            rows.append((s, int(start), obj_row[(s, name)]))
            cats.append(seq.objects[name].category)
    if not rows:
        raise ValueError(f"split {split!r} of {data_dir} has no sequence with an object track, rotations and at "
                         f">= {window} frames; the filter trains on human-object sequences")
    names = sorted(set(cats)) if categories is None else list(categories)
    lut = {c: i for i, c in enumerate(names)}
    keep = np.array([c in lut for c in cats])
    return FilterWindows(human=human, objects=objects, offsets=np.stack(offsets), windows=np.array(rows, np.int64)[keep],
                         categories=np.array([lut[c] for c in cats if c in lut], np.int64), category_names=names,
                         files=files, window=window, fps=fps)
