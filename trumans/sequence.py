"""The sequence file format (docs/conventions.md "File formats"): one ``.npz`` per clip, read without pickle.

Keys: ``joints (T,24,3) float32`` (m, z-up world), ``fps ()``, optional ``rotations (T,24,6)``
(6D local, root first) and ``root_pos (T,3)``, ``actions (T,N_A)`` + ``action_names (N_A,)``,
``contacts (T,24) bool``, ``scene`` (id or path), and per dynamic object
``objects/<name>/pose (T,4,4)``, ``objects/<name>/category``, optional ``objects/<name>/imu_rot (T,6)``,
``objects/<name>/imu_acc (T,3)``. Extra arrays live under ``extra/<key>``.
"""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trumans.scenes.atomic import atomic_write  # the one implementation; re-exported here

from .input_files import check_input_file
from .limits import check_fps
from .skeleton import NUM_JOINTS

__all__ = ["ObjectTrack", "Sequence", "save_sequence", "load_sequence", "atomic_write", "SAMPLER_CONFIG_KEY",
           "GOALS_KEY", "GOAL_JOINTS_KEY"]

# ``extra`` entries of a sequence made by ``trumans sample``: the sampler config used, JSON
# (``SamplerConfig.to_dict``; ``SamplerConfig.from_dict(json.loads(...))`` rebuilds it); every episode's
# goal, ``extra[GOALS_KEY]`` (K, 4) rows (frame, x, y, z) m, the frame it is due (a pelvis goal is a floor
# point, z = 0), and ``extra[GOAL_JOINTS_KEY]`` (K,) the joint that reaches it (``trumans view --html``
# draws them; ``trumans eval realism --generated`` reads the episode cycle from them)
SAMPLER_CONFIG_KEY = "sampler_config"
GOALS_KEY, GOAL_JOINTS_KEY = "goals", "goal_joints"


@dataclass
class ObjectTrack:
    """A dynamic object's trajectory: pose (T, 4, 4) world-from-object, category name."""

    pose: np.ndarray
    category: str
    imu_rot: np.ndarray | None = None  # (T, 6)
    imu_acc: np.ndarray | None = None  # (T, 3), m/s^2


@dataclass
class Sequence:
    """One motion clip. joints: (T, 24, 3) float32 metres, z-up world; fps in Hz."""

    joints: np.ndarray
    fps: float
    rotations: np.ndarray | None = None  # (T, 24, 6) local 6D
    root_pos: np.ndarray | None = None  # (T, 3) FK root translation (pelvis), m
    actions: np.ndarray | None = None  # (T, N_A), 0 off, 1 + progress while on
    action_names: list[str] = field(default_factory=list)
    contacts: np.ndarray | None = None  # (T, 24) bool
    scene: str = ""
    objects: dict[str, ObjectTrack] = field(default_factory=dict)
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    # True for tracked input (``trumans refine``): NaN entries in joints / rotations / object poses /
    # IMU mark missing measurements (a dropped frame, an occluded joint). False: every value finite.
    allow_missing: bool = False

    def __post_init__(self) -> None:
        self.joints = np.asarray(self.joints, dtype=np.float32)
        self.validate()

    @property
    def num_frames(self) -> int:
        return int(self.joints.shape[0])

    def validate(self) -> None:
        """Raise ValueError naming the first inconsistent field."""
        j = self.joints
        if j.ndim != 3 or j.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"joints must be (T, 24, 3), got {j.shape}")
        if np.isinf(j).any() or (not self.allow_missing and np.isnan(j).any()):
            raise ValueError("joints contain NaN or inf; clean the sequence before saving/using it "
                             "(tracked input with missing frames: load it with allow_missing=True)")
        check_fps(self.fps, "the sequence's fps")
        T = j.shape[0]
        if self.rotations is not None and np.shape(self.rotations) != (T, NUM_JOINTS, 6):
            raise ValueError(f"rotations must be ({T}, 24, 6), got {np.shape(self.rotations)}")
        if self.root_pos is not None and np.shape(self.root_pos) != (T, 3):
            raise ValueError(f"root_pos must be ({T}, 3), got {np.shape(self.root_pos)}")
        if self.actions is not None:
            a = np.asarray(self.actions)
            if a.ndim != 2 or a.shape[0] != T or a.shape[1] != len(self.action_names):
                raise ValueError(
                    f"actions must be ({T}, {len(self.action_names)}) to match action_names, got {a.shape}")
        if self.contacts is not None and np.shape(self.contacts) != (T, NUM_JOINTS):
            raise ValueError(f"contacts must be ({T}, 24), got {np.shape(self.contacts)}")
        for name, ob in self.objects.items():
            if "/" in name or not name:
                raise ValueError(f"object name {name!r} must be non-empty and contain no '/'")
            if np.shape(ob.pose) != (T, 4, 4):
                raise ValueError(f"objects/{name}/pose must be ({T}, 4, 4), got {np.shape(ob.pose)}")


def save_sequence(seq: Sequence, path: str | Path) -> None:
    """Write ``seq`` to ``path`` (.npz, uncompressed, atomically). A sequence needs >= 1 frame."""
    seq.validate()
    if seq.num_frames == 0:
        raise ValueError(f"sequence for {path} has no frames; a sequence needs at least one")
    arrays: dict[str, np.ndarray] = {
        "joints": seq.joints.astype(np.float32),
        "fps": np.asarray(seq.fps, dtype=np.float32),
        "scene": np.asarray(str(seq.scene)),
    }
    if seq.rotations is not None:
        arrays["rotations"] = np.asarray(seq.rotations, dtype=np.float32)
    if seq.root_pos is not None:
        arrays["root_pos"] = np.asarray(seq.root_pos, dtype=np.float32)
    if seq.actions is not None:
        arrays["actions"] = np.asarray(seq.actions, dtype=np.float32)
        arrays["action_names"] = np.asarray(list(seq.action_names), dtype=np.str_)
    if seq.contacts is not None:
        arrays["contacts"] = np.asarray(seq.contacts, dtype=bool)
    for name, ob in seq.objects.items():
        arrays[f"objects/{name}/pose"] = np.asarray(ob.pose, dtype=np.float32)
        arrays[f"objects/{name}/category"] = np.asarray(ob.category)
        if ob.imu_rot is not None:
            arrays[f"objects/{name}/imu_rot"] = np.asarray(ob.imu_rot, dtype=np.float32)
        if ob.imu_acc is not None:
            arrays[f"objects/{name}/imu_acc"] = np.asarray(ob.imu_acc, dtype=np.float32)
    for k, v in seq.extra.items():
        arrays[f"extra/{k}"] = np.asarray(v)

    def _write(tmp: str) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)

    atomic_write(path, _write)


def load_sequence(path: str | Path, allow_missing: bool = False) -> Sequence:
    """Read a sequence ``.npz`` (never unpickles). Raises FileNotFoundError / ValueError with the fix.
    allow_missing: accept NaN (= missing) entries, as in tracked input (``Sequence.allow_missing``)."""
    path = check_input_file(path, "sequence file", "pass a sequence .npz")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as e:
        # numpy's pickle message suggests unsafe loading: never; say what the file is not instead
        why = "not an .npz archive; unpickling is refused" if "pickle" in str(e) else str(e)
        raise ValueError(f"{path} is not a readable sequence .npz ({why}); re-create or re-export it") from e
    if "joints" not in data or "fps" not in data:
        raise ValueError(f"{path} lacks 'joints' and/or 'fps'; it is not a trumans sequence file")
    for k, v in data.items():  # every array is numeric, bool or text (object arrays were refused above)
        if v.dtype.kind not in "biufU":
            raise ValueError(f"{path}: '{k}' has dtype {v.dtype}; re-create or re-export the sequence")
    for k in ("joints", "rotations", "root_pos", "actions") + tuple(x for x in data if x.startswith("objects/")
                                                                    and not x.endswith("/category")):
        if k in data and data[k].dtype.kind not in "biuf":
            raise ValueError(f"{path}: '{k}' must be numeric, got dtype {data[k].dtype}; re-create or re-export it")
    if data["fps"].size != 1 or data["fps"].dtype.kind not in "iuf":
        raise ValueError(f"{path}: 'fps' must be one number, got shape {data['fps'].shape} dtype {data['fps'].dtype}")
    if data["joints"].ndim != 3 or data["joints"].shape[0] == 0:
        raise ValueError(f"{path}: 'joints' must be (T, 24, 3) with T >= 1 frames, got {data['joints'].shape}; "
                         f"re-create or re-export the sequence")
    for k in ("scene", "action_names"):
        if k in data and data[k].dtype.kind != "U":
            raise ValueError(f"{path}: '{k}' must be text, got dtype {data[k].dtype}")
    objects: dict[str, ObjectTrack] = {}
    for k in data:
        if k.startswith("objects/") and k.endswith("/pose"):
            name = k[len("objects/"):-len("/pose")]
            pre = f"objects/{name}/"
            objects[name] = ObjectTrack(
                pose=data[k],
                category=str(data.get(pre + "category", np.asarray(""))),
                imu_rot=data.get(pre + "imu_rot"),
                imu_acc=data.get(pre + "imu_acc"),
            )
    try:
        return Sequence(
            joints=data["joints"],
            fps=float(data["fps"].reshape(())),
            rotations=data.get("rotations"),
            root_pos=data.get("root_pos"),
            actions=data.get("actions"),
            action_names=[str(s) for s in data.get("action_names", [])],
            contacts=data.get("contacts"),
            scene=str(data.get("scene", "")),
            objects=objects,
            extra={k[len("extra/"):]: v for k, v in data.items() if k.startswith("extra/")},
            allow_missing=allow_missing,
        )
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from e
