"""Reader for the TRUMANS release layout (docs/conventions.md "File formats / Dataset"), mapped to trumans types.

Release layout (one folder, all frames of all sequences concatenated, 30 fps, y-up, metres):
- ``human_joints.npy``  (N, 24, 3) joint positions, SMPL-X body joints 0-21 + two hand joints, y up;
- ``action_label.npy``  (N, N_A) frame-wise multi-hot action labels (optional);
- ``idx_start.npy``     (S,) first frame of each sequence (optional: otherwise sequences are cut
  where ``scene_flag`` changes);
- ``scene_flag.npy``    (N,) index into the sorted file list of ``Scene/`` (optional);
- ``Scene/*.npy``       (300, 100, 400) bool occupancy, 2 cm voxels spanning x in [-3, 3],
  y (up) in [0, 2], z in [-4, 4] (the bounds used by the authors' loader);
- ``object_flag.npy``   (N, N_obj) int, >= 0 where object ``o`` is present: index into
  ``object_mat[n]``; ``object_mat.npy`` (N, K, 4, 4) object poses in the y-up world, applied to
  row vectors (``p_world = p @ M[:3, :3] + M[:3, 3]``), as the authors' loader does;
  ``object_names.json`` (optional) names the N_obj objects.

Conversion to z-up: a proper rotation of +90 degrees about x, ``(x, y, z)_yup -> (x, -z, y)_zup``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trumans.input_files import file_kind, parse_json
from trumans.limits import check_npy_size
from trumans.scenes.io import Y_UP_TO_Z_UP  # the one y-up -> z-up turn, shared with mesh import
from trumans.scenes.occupancy import OccupancyGrid
from trumans.sequence import ObjectTrack, Sequence

__all__ = ["Y_UP_TO_Z_UP", "TrumansRelease", "read_release", "release_grid_to_z_up", "RELEASE_GRID_BOUNDS"]

RELEASE_GRID_BOUNDS = np.array([[-3.0, 0.0, -4.0], [3.0, 2.0, 4.0]])  # y-up min / max corners, m
RELEASE_GRID_SHAPE = (300, 100, 400)
RELEASE_FPS = 30.0


@dataclass
class TrumansRelease:
    sequences: list[Sequence]
    scenes: dict[str, OccupancyGrid]


def release_grid_to_z_up(grid_yup: np.ndarray) -> OccupancyGrid:
    """(300, 100, 400) y-up grid [ix, iy(up), iz] -> z-up grid [ix, jy, kz] with y' = -z, z' = y."""
    if grid_yup.ndim != 3:
        raise ValueError(f"a release scene grid must be 3D, got shape {grid_yup.shape}")
    shape = np.array(grid_yup.shape)
    voxel_yup = (RELEASE_GRID_BOUNDS[1] - RELEASE_GRID_BOUNDS[0]) / shape
    if not np.allclose(voxel_yup, voxel_yup[0]):
        raise ValueError(f"scene grid of shape {tuple(shape)} does not give cubic voxels over the release bounds")
    grid = np.flip(np.transpose(grid_yup.astype(bool), (0, 2, 1)), axis=1)
    v = float(voxel_yup[0])
    # z-up min corner: x_min, -z_max, y_min.
    lo = np.array([RELEASE_GRID_BOUNDS[0, 0], -RELEASE_GRID_BOUNDS[1, 2], RELEASE_GRID_BOUNDS[0, 1]])
    return OccupancyGrid(grid=np.ascontiguousarray(grid), origin=lo + 0.5 * v, voxel=v)


def _load(folder: Path, name: str, required: bool = True) -> np.ndarray | None:
    p = folder / name
    if not p.is_file():
        if required:
            raise FileNotFoundError(f"{p} is missing: a TRUMANS release folder needs {name}")
        return None
    check_npy_size(p)  # before np.load allocates what the header declares
    try:
        return np.load(p, allow_pickle=False)
    except (ValueError, OSError, EOFError) as e:
        # numpy's pickle message suggests unsafe loading: never; say what the file is instead
        why = "it holds Python objects; unpickling is refused" if "pickle" in str(e) else str(e)
        raise ValueError(f"{p} is not a readable .npy array ({why}); re-download or re-export it") from e


def _read_names(path: Path, n: int) -> list[str]:
    try:
        names = parse_json(path.read_text(), f"object-name file {path}", f"it must be a flat list of the {n} object names")
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path} is not valid JSON ({e}); it must list the {n} object names") from e
    if not isinstance(names, list) or len(names) != n or not all(isinstance(x, str) and x and "/" not in x
                                                                   for x in names):
        raise ValueError(f"{path} must be a JSON list of {n} object names (text without '/'), got {str(names)[:60]}")
    return names


def _segments(n: int, idx_start: np.ndarray | None, scene_flag: np.ndarray | None) -> list[tuple[int, int]]:
    if idx_start is not None:
        starts = np.unique(np.asarray(idx_start, dtype=np.int64).ravel())
        if starts.size == 0 or starts[0] < 0 or starts[-1] >= n:
            raise ValueError(f"idx_start.npy must hold frame indices in [0, {n}), got range "
                             f"[{starts.min() if starts.size else '-'}, {starts.max() if starts.size else '-'}]")
        if starts[0] != 0:
            starts = np.concatenate([[0], starts])
    elif scene_flag is not None:
        starts = np.concatenate([[0], np.flatnonzero(np.diff(scene_flag) != 0) + 1])
    else:
        starts = np.array([0])
    ends = np.concatenate([starts[1:], [n]])
    return [(int(s), int(e)) for s, e in zip(starts, ends) if e > s]


def read_release(folder: str | Path, action_names: list[str] | None = None, fps: float = RELEASE_FPS) -> TrumansRelease:
    """Read a TRUMANS release folder into z-up Sequences (one per segment) and z-up scene grids.

    Sequence ``scene`` fields hold the scene file stem (e.g. ``"0a1b..."``) when ``scene_flag`` exists.
    """
    folder = Path(folder)
    if not folder.is_dir():
        if file_kind(folder) is not None:
            raise ValueError(f"TRUMANS release folder {folder} is a {file_kind(folder)}, not a folder")
        raise FileNotFoundError(f"TRUMANS release folder {folder} does not exist")
    joints = _load(folder, "human_joints.npy")
    if joints.ndim != 3 or joints.shape[1:] != (24, 3):
        raise ValueError(f"human_joints.npy must be (N, 24, 3), got {joints.shape}")
    if not np.isfinite(joints).all():
        raise ValueError("human_joints.npy contains NaN or inf")
    n = joints.shape[0]
    if n == 0:
        raise ValueError(f"{folder / 'human_joints.npy'} holds 0 frames; there is nothing to import")
    actions = _load(folder, "action_label.npy", required=False)
    if actions is not None:
        if actions.ndim != 2 or actions.shape[0] != n:
            raise ValueError(f"action_label.npy must be ({n}, N_A), got {actions.shape}")
        if action_names is None:
            action_names = [f"action_{i:02d}" for i in range(actions.shape[1])]
        if len(action_names) != actions.shape[1]:
            raise ValueError(f"{len(action_names)} action names given for {actions.shape[1]} label columns")
        if not np.isfinite(actions).all():
            t, a = np.argwhere(~np.isfinite(actions))[0]
            raise ValueError(f"action_label.npy holds NaN or inf (first at frame {t}, column {a}); labels must be "
                             f"finite (0 off, 1 + progress on)")
    scene_flag = _load(folder, "scene_flag.npy", required=False)
    if scene_flag is not None:
        if scene_flag.shape != (n,) or scene_flag.dtype.kind not in "iu":
            raise ValueError(f"scene_flag.npy must be ({n},) integers, got {scene_flag.shape} {scene_flag.dtype}")
        if scene_flag.min() < 0:
            raise ValueError(f"scene_flag.npy holds {int(scene_flag.min())} at frame {int(np.argmin(scene_flag))}; "
                             f"scene indices must be >= 0 (they index the sorted files of Scene/)")
    scene_files = sorted((folder / "Scene").glob("*.npy")) if (folder / "Scene").is_dir() else []
    scenes = {}
    for f in scene_files:
        g = _load(f.parent, f.name)
        scenes[f.stem] = release_grid_to_z_up(g)
    if scene_flag is not None and scene_files and scene_flag.max() >= len(scene_files):
        raise ValueError(f"scene_flag.npy refers to scene {int(scene_flag.max())} but Scene/ holds {len(scene_files)} grids")

    obj_flag = _load(folder, "object_flag.npy", required=False)
    obj_mat = _load(folder, "object_mat.npy", required=False)
    obj_names: list[str] | None = None
    if obj_flag is not None:
        if obj_mat is None:
            raise FileNotFoundError(f"{folder / 'object_mat.npy'} is missing but object_flag.npy exists")
        if obj_flag.ndim != 2 or obj_flag.shape[0] != n or obj_mat.shape[0] != n or obj_mat.shape[-2:] != (4, 4):
            raise ValueError(f"object_flag.npy must be ({n}, N_obj) and object_mat.npy ({n}, K, 4, 4); "
                             f"got {obj_flag.shape} and {obj_mat.shape}")
        names_file = folder / "object_names.json"
        obj_names = (_read_names(names_file, obj_flag.shape[1]) if names_file.is_file()
                     else [f"object_{i:02d}" for i in range(obj_flag.shape[1])])
        obj_categories = list(obj_names)  # the release names an object by its category
        if len(set(obj_names)) < len(obj_names):  # a sequence keys its objects by name: one would be lost
            seen: dict[str, int] = {}
            for k, nm in enumerate(obj_names):
                seen[nm] = seen.get(nm, 0) + 1
                if seen[nm] > 1:
                    obj_names[k] = f"{nm}_{seen[nm] - 1}"
        if obj_flag.dtype.kind not in "iu":
            raise ValueError(f"object_flag.npy must hold integers (-1 absent, else the row of object_mat.npy), "
                             f"got {obj_flag.dtype}")
        if obj_mat.ndim != 4 or obj_flag.max(initial=-1) >= obj_mat.shape[1]:
            raise ValueError(f"object_flag.npy refers to row {int(obj_flag.max())} of object_mat.npy, which holds "
                             f"{obj_mat.shape[1] if obj_mat.ndim == 4 else '?'} per frame")

    C = Y_UP_TO_Z_UP
    joints_z = joints.astype(np.float64) @ C.T
    sequences = []
    for s, e in _segments(n, _load(folder, "idx_start.npy", required=False), scene_flag):
        objects: dict[str, ObjectTrack] = {}
        if obj_flag is not None:
            flags = obj_flag[s:e]
            for o in np.flatnonzero((flags >= 0).any(axis=0)):
                present = flags[:, o] >= 0
                idx = np.where(present, flags[:, o], 0)
                M = obj_mat[np.arange(s, e), idx].astype(np.float64)  # (T, 4, 4), row-vector form
                if not np.isfinite(M[present]).all():
                    t = s + int(np.flatnonzero(~np.isfinite(M).all((1, 2)) & present)[0])
                    raise ValueError(f"object_mat.npy holds NaN or inf for object {obj_names[o]!r} at frame {t}, "
                                     f"where object_flag.npy says it is present")
                pose = np.tile(np.eye(4), (e - s, 1, 1))
                pose[:, :3, :3] = C @ np.swapaxes(M[:, :3, :3], 1, 2) @ C.T  # column-vector, z-up
                pose[:, :3, 3] = M[:, :3, 3] @ C.T
                first = int(np.argmax(present))
                pose[~present] = pose[first]  # absent frames hold the first seen pose
                objects[obj_names[o]] = ObjectTrack(pose=pose.astype(np.float32), category=obj_categories[o])
        seq = Sequence(
            joints=joints_z[s:e].astype(np.float32),
            fps=fps,
            actions=None if actions is None else actions[s:e].astype(np.float32),
            action_names=list(action_names or []),
            scene=(scene_files[int(scene_flag[s])].stem if scene_flag is not None and scene_files else ""),
            objects=objects,
        )
        sequences.append(seq)
    return TrumansRelease(sequences=sequences, scenes=scenes)
