"""The shipped real-motion corpus (``data/mocap/cmu_corpus.npz``): CMU mocap clips as our 24 joints.

Each clip is converted once (``scripts/build_mocap_corpus.py``) from the raw CMU files: imported
through ``trumans.importers.fbx`` / ``trumans.bvh`` with the Daz / CMU joint maps, the converter's
synthetic T-pose first frame dropped, resampled once to 30 fps (``trumans.resample.resample_joints_smooth``: a zero-phase
6 Hz low-pass against the keys' marker noise, a cubic spline, bone lengths kept), feet put on the floor, and labelled per frame with ``trumans.motion_labels``.
Joints are stored losslessly to 0.1 mm: quantised to int (1e-4 m), the first frame and first
velocity as int32, the rest as int16 second differences (zlib-compressed), so the corpus is a
few MB. Clips of the held-out CMU subjects (``split ==
"test"``) are the reference of ``trumans eval realism`` and are not used for tuning.
"""
from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bvh import CORPUS_FROM_PROJECT_TURN, CORPUS_Y_UP_FROM_Z_UP
from .importers.labels import drop_tpose_frame  # the converters' T-pose rule, defined with the importers
from .motion_labels import MOTION_STATES
from trumans.paths import DATA_DIR

__all__ = ["CORPUS_PATH", "QUANTUM_M", "HELD_OUT_SUBJECTS", "MocapClip", "encode_joints", "decode_joints",
           "write_corpus", "load_corpus", "drop_tpose_frame", "source_joints", "convert_clip"]

CORPUS_PATH = DATA_DIR / "mocap" / "cmu_corpus.npz"
QUANTUM_M = 1e-4
HELD_OUT_SUBJECTS = ("08", "86", "111", "114", "132")  # walking, sitting down / up, lying: evaluation only


@dataclass
class MocapClip:
    """One corpus clip: joints (T, 24, 3) float32 m at ``fps``, per-frame ``states`` (T,) indices
    into ``MOTION_STATES``, CMU trial name, subject, description and split ("train" | "test")."""

    name: str
    subject: str
    description: str
    split: str
    fps: float
    joints: np.ndarray
    states: np.ndarray


def encode_joints(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T >= 2, 24, 3) m -> (start (2, 24, 3) int32: first frame and first step, d2 (T-2, 24, 3) int16)."""
    q = np.round(np.asarray(joints, np.float64) / QUANTUM_M).astype(np.int64)
    if len(q) < 2:
        raise ValueError(f"a clip needs at least 2 frames to encode, got {len(q)}")
    start = np.stack([q[0], q[1] - q[0]]).astype(np.int32)
    d2 = np.diff(q, n=2, axis=0)
    if np.abs(d2).max(initial=0) > np.iinfo(np.int16).max:
        raise ValueError(f"a joint accelerates by {np.abs(d2).max() * QUANTUM_M:.3f} m per frame^2; the clip has a "
                         "jump (check the source file) and cannot be encoded as int16 steps")
    return start, d2.astype(np.int16)


def decode_joints(start: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Inverse of ``encode_joints``: (T, 24, 3) float32 m."""
    vel = np.concatenate([start[1:2].astype(np.int64), d2.astype(np.int64)]).cumsum(axis=0)
    q = np.concatenate([start[:1].astype(np.int64), start[:1] + vel.cumsum(axis=0)])
    return (q * QUANTUM_M).astype(np.float32)


def write_corpus(path: str | Path, clips: list[MocapClip], meta: dict) -> None:
    """Write clips to one npz whose bytes depend only on the clips (fixed zip timestamps)."""
    starts, d2s = zip(*(encode_joints(c.joints) for c in clips))
    arrays = {
        "start": np.stack(starts), "d2": np.concatenate(d2s),
        "lengths": np.array([len(c.joints) for c in clips], np.int64),
        "states": np.concatenate([c.states for c in clips]).astype(np.int8),
        "fps": np.array([c.fps for c in clips], np.float64),
        "names": np.array([c.name for c in clips]), "subjects": np.array([c.subject for c in clips]),
        "descriptions": np.array([c.description for c in clips]), "splits": np.array([c.split for c in clips]),
        "state_names": np.array(MOTION_STATES), "meta": np.array(json.dumps(meta, sort_keys=True)),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        for key in sorted(arrays):
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.ascontiguousarray(arrays[key]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(info, buf.getvalue(), compresslevel=9)


def load_corpus(path: str | Path | None = None, split: str | None = None) -> list[MocapClip]:
    """The corpus clips (all, or those of ``split`` "train" / "test"). Never executes code."""
    path = Path(path) if path is not None else CORPUS_PATH
    if not path.is_file():
        raise FileNotFoundError(f"mocap corpus {path} does not exist; rebuild it with "
                                "scripts/build_mocap_corpus.py (needs the raw CMU files)")
    if split not in (None, "train", "test"):
        raise ValueError(f"split must be 'train', 'test' or None, got {split!r}")
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in z.files}
    names = [str(s) for s in a["state_names"]]
    if names != list(MOTION_STATES):
        raise ValueError(f"{path} labels states {names}, this code expects {list(MOTION_STATES)}; rebuild it")
    ends = np.cumsum(a["lengths"])
    out = []
    for i, n in enumerate(a["lengths"]):
        if split is not None and a["splits"][i] != split:
            continue
        e = int(ends[i])
        s = e - int(n)
        d2 = a["d2"][s - 2 * i:e - 2 * (i + 1)]
        out.append(MocapClip(name=str(a["names"][i]), subject=str(a["subjects"][i]),
                             description=str(a["descriptions"][i]), split=str(a["splits"][i]),
                             fps=float(a["fps"][i]), joints=decode_joints(a["start"][i], d2),
                             states=a["states"][s:e].astype(np.int64)))
    return out


def source_joints(path: str | Path) -> tuple[np.ndarray, float]:
    """The raw keys of one CMU file (.fbx or .bvh) as our 24 joints, unresampled: ((T, 24, 3) float64
    m z-up at the file's key times, key rate Hz). FBX curves are evaluated at their keys (exact),
    BVH frames are read as they are; the converters' synthetic T-pose first frame is dropped."""
    from .bvh import BvhData, read_bvh
    from .importers import fbx
    from .importers.joint_maps import guess_unit_scale, retarget_joints

    path = Path(path)
    if path.suffix.lower() == ".fbx":
        scene = fbx.read_fbx(path)
        t0, t1 = scene.time_range()
        kf = scene.key_fps()
        if kf is None:
            raise ValueError(f"{path}: no animation")
        names, P = fbx.joint_positions(scene, t0 + np.arange(int(round((t1 - t0) * kf)) + 1) / kf)
        P = P @ CORPUS_FROM_PROJECT_TURN  # the corpus keeps its own horizontal axes (trumans.bvh.CORPUS_Y_UP_FROM_Z_UP)
        src_fps = kf
    elif path.suffix.lower() == ".bvh":
        b = read_bvh(path)
        Pw, Gw = b.forward_kinematics()
        ends = sorted(b.end_sites)
        names = b.names + [f"{b.names[j]}_end" for j in ends]
        if ends:
            Pw = np.concatenate([Pw, np.stack([Pw[:, j] + Gw[:, j] @ b.end_sites[j] for j in ends], 1)], 1)
        rest, _ = BvhData(b.names, b.parents, b.offsets, [[] for _ in b.names], np.zeros((1, 0)), 1.0).forward_kinematics()
        scale = guess_unit_scale(float(np.ptp((rest[0] @ CORPUS_Y_UP_FROM_Z_UP)[:, 2])))
        P = Pw @ CORPUS_Y_UP_FROM_Z_UP * scale  # y-up file -> z-up ours
        src_fps = b.fps
    else:
        raise ValueError(f"{path}: expected a .fbx or .bvh file")
    return drop_tpose_frame(retarget_joints(names, P)), float(src_fps)


def convert_clip(path: str | Path, name: str, description: str = "", fps: float = 30.0) -> MocapClip:
    """Convert one raw CMU file (.fbx or .bvh) into a corpus clip (joints only: no rotation fit):
    its keys (``source_joints``) resampled once to ``fps`` (``trumans.resample.resample_joints_smooth``),
    feet on the floor, stored to 0.1 mm, labelled per frame."""
    from .importers.joint_maps import place_on_floor
    from .motion_labels import label_states
    from .resample import resample_joints_smooth
    from .sequence import Sequence

    keys, src_fps = source_joints(path)
    joints = resample_joints_smooth(keys, src_fps, fps)
    seq = place_on_floor(Sequence(joints=joints.astype(np.float32), fps=float(fps)), True, source=str(path))
    joints = decode_joints(*encode_joints(seq.joints))  # what the corpus stores
    subject = name.split("_")[0]
    return MocapClip(name=name, subject=subject, description=description,
                     split="test" if subject in HELD_OUT_SUBJECTS else "train", fps=float(fps), joints=joints,
                     states=label_states(joints, fps))
