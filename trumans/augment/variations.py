"""Object variations (TRUMANS §3.3): scale per axis, move, or replace by another instance of the
same category, and the matching contact point on the changed object.

Normalised coordinates (convention owned here): a point's position in the object's local
axis-aligned bounding box, ``u = (p_local - bbox_min) / (bbox_max - bbox_min)`` in [0, 1]^3.
A contact point ``v_m`` on the old object maps to the point with the same ``u`` in the new
object's box, projected to the new surface (closest point): ``v'_m``. Scaling is about the
bottom centre of the local box (the object stays on the floor); moves are a horizontal
translation plus a yaw about the bottom centre.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Literal

import numpy as np
import trimesh

from trumans.scenes._open3d import open3d_module
from trumans.scenes.raycast import to_o3d_scene
from trumans.scenes.scene import SceneObject
from trumans.rotations import yaw_matrix

__all__ = [
    "Variation",
    "VariationKind",
    "bottom_centre",
    "normalized_coords",
    "apply_variation",
    "map_contact_points",
    "move_matrix",
    "closest_on_mesh",
    "sample_variation",
]

VariationKind = Literal["scale", "move", "replace"]
KINDS: tuple[str, ...] = ("scale", "move", "replace")


@dataclass
class Variation:
    """A change of one object. scale: (3,) per-axis factors (object frame); translation: (3,)
    world m (z ignored: objects stay on the floor); yaw: rad about world z; replacement: name of
    the library instance that replaces the object (kind 'replace')."""

    object: str
    kind: VariationKind
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    yaw: float = 0.0
    replacement: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"variation kind must be one of {KINDS}, got {self.kind!r}")
        s = np.asarray(self.scale, dtype=np.float64)
        if s.shape != (3,) or not np.all(s > 0):
            raise ValueError(f"scale must be three positive factors, got {self.scale}")
        if self.kind == "replace" and not self.replacement:
            raise ValueError("a 'replace' variation needs the replacement instance's name")
        self.scale = tuple(float(x) for x in s)
        self.translation = tuple(float(x) for x in np.asarray(self.translation, dtype=np.float64).reshape(3))
        self.yaw = float(self.yaw)

    def to_json(self) -> dict:
        return asdict(self)


def bottom_centre(mesh: trimesh.Trimesh) -> np.ndarray:
    """(3,) centre of the bottom face of the mesh's axis-aligned box (its own frame)."""
    lo, hi = mesh.bounds
    return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])


def _to_local(obj: SceneObject, p: np.ndarray) -> np.ndarray:
    inv = np.linalg.inv(obj.pose)
    return p @ inv[:3, :3].T + inv[:3, 3]


def _to_world(obj: SceneObject, p: np.ndarray) -> np.ndarray:
    return p @ obj.pose[:3, :3].T + obj.pose[:3, 3]


def normalized_coords(obj: SceneObject, points: np.ndarray) -> np.ndarray:
    """points: (N, 3) world m -> (N, 3) bounding-box-normalised local coordinates (module doc)."""
    lo, hi = obj.mesh.bounds
    return (_to_local(obj, np.asarray(points, dtype=np.float64)) - lo) / np.maximum(hi - lo, 1e-9)


def closest_on_mesh(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(N, 3) points -> (N, 3) closest points on ``mesh`` (same frame), via open3d ray casting."""
    scene, _ = to_o3d_scene(mesh)
    q = open3d_module().core.Tensor(np.ascontiguousarray(points, dtype=np.float32))
    return scene.compute_closest_points(q, nthreads=1)["points"].numpy().astype(np.float64)


def apply_variation(obj: SceneObject, var: Variation, replacement: trimesh.Trimesh | None = None) -> SceneObject:
    """The changed object (a new SceneObject; ``obj`` is not modified).

    replacement: the mesh (its own frame) of the new instance for kind 'replace'; it is placed so
    that its box's bottom centre coincides with the old one's (same pose, same facing)."""
    if var.object != obj.name:
        raise ValueError(f"variation is for object {var.object!r}, not {obj.name!r}")
    mesh = obj.mesh.copy()
    pose = obj.pose.copy()
    meta = dict(obj.meta)
    c = bottom_centre(obj.mesh)
    if var.kind == "scale":
        s = np.asarray(var.scale)
        mesh.vertices = c + (np.asarray(mesh.vertices) - c) * s
        meta = _scale_meta(meta, c, s)
    elif var.kind == "move":
        cw = _to_world(obj, c[None])[0]
        R = np.eye(4)
        R[:3, :3] = yaw_matrix(var.yaw)
        M = np.eye(4)
        M[:3, 3] = cw + np.array([var.translation[0], var.translation[1], 0.0])
        M_back = np.eye(4)
        M_back[:3, 3] = -cw
        pose = M @ R @ M_back @ pose
    else:
        if replacement is None:
            raise ValueError(f"variation 'replace' of {obj.name!r} needs the replacement mesh {var.replacement!r}")
        if len(replacement.faces) == 0:
            raise ValueError(f"replacement mesh {var.replacement!r} is empty")
        mesh = replacement.copy()
        mesh.apply_translation(c - bottom_centre(mesh))
        meta = {k: v for k, v in meta.items() if not isinstance(v, (list, tuple))}  # old points are void
        meta["replaced_by"] = var.replacement
    return SceneObject(name=obj.name, category=obj.category, mesh=mesh, pose=pose, dof=obj.dof,
                       hinge_point=obj.hinge_point, axis=obj.axis, dynamic=obj.dynamic, meta=meta)


def _scale_meta(meta: dict, c: np.ndarray, s: np.ndarray) -> dict:
    """Scale JSON semantics: '*height' numbers by s_z (measured from the bottom), 3-vectors and
    lists of 3-vectors (local points) about the bottom centre."""
    out = {}
    for k, v in meta.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool) and k.endswith("height"):
            out[k] = float(c[2] + (v - c[2]) * s[2])
        elif isinstance(v, (list, tuple)) and len(v) == 3 and all(isinstance(x, (int, float)) for x in v):
            out[k] = (c + (np.asarray(v, float) - c) * s).tolist()
        elif (isinstance(v, (list, tuple)) and v and all(isinstance(x, (list, tuple)) and len(x) == 3 for x in v)):
            out[k] = (c + (np.asarray(v, float) - c) * s).tolist()
        else:
            out[k] = v
    return out


def move_matrix(old: SceneObject, new: SceneObject) -> np.ndarray:
    """(4, 4) world transform M with new.pose = M @ old.pose (identity unless the object moved);
    a pose track of a dynamic object maps the same way: new_pose_t = M @ pose_t."""
    return new.pose @ np.linalg.inv(old.pose)


def map_contact_points(old: SceneObject, new: SceneObject, points: np.ndarray,
                       poses: np.ndarray | None = None) -> np.ndarray:
    """Contact points (N, 3) world on ``old`` -> matching points (N, 3) world on ``new``: same
    normalised coordinates, projected to the new surface. poses: optional (N, 4, 4) per-point
    world-from-object poses of ``old`` (a moving object); default ``old.pose``."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        return p.copy()
    if poses is None:
        poses = np.broadcast_to(old.pose, (len(p), 4, 4))
    poses = np.asarray(poses, dtype=np.float64)
    if poses.shape != (len(p), 4, 4):
        raise ValueError(f"poses must be ({len(p)}, 4, 4), got {poses.shape}")
    inv = np.linalg.inv(poses)
    local = np.einsum("nij,nj->ni", inv[:, :3, :3], p) + inv[:, :3, 3]
    lo, hi = old.mesh.bounds
    u = (local - lo) / np.maximum(hi - lo, 1e-9)
    lo2, hi2 = new.mesh.bounds
    local2 = closest_on_mesh(new.mesh, lo2 + u * (hi2 - lo2))
    new_poses = move_matrix(old, new) @ poses
    return np.einsum("nij,nj->ni", new_poses[:, :3, :3], local2) + new_poses[:, :3, 3]


def sample_variation(obj: SceneObject, rng: np.random.Generator, kinds: tuple[str, ...] = KINDS,
                     library: dict[str, trimesh.Trimesh] | None = None, max_scale: float = 0.15,
                     max_move: float = 0.15, max_size_ratio: float = 1.3) -> Variation:
    """A random variation of ``obj``: height change of up to +-max_scale m (the paper's +-15 cm)
    with a milder footprint change, a move of up to max_move m with a yaw of up to 10 deg, or
    a replacement drawn from ``library`` (name -> mesh of the same category, only those whose box
    extents are all within a factor ``max_size_ratio`` of the object's; skipped if none)."""
    if library:
        # only instances of a similar size (every box extent within max_size_ratio): a person's
        # motion can follow a taller chair, not a chair turned into a stool
        ext = np.maximum(obj.mesh.extents, 1e-6)
        library = {k: m for k, m in library.items()
                   if np.abs(np.log(np.maximum(m.extents, 1e-6) / ext)).max() <= np.log(max_size_ratio)}
    kinds = tuple(k for k in kinds if k != "replace" or library)
    if not kinds:
        raise ValueError(f"no variation kind available for {obj.name!r} (replace needs a library)")
    kind = str(rng.choice(kinds))
    if kind == "scale":
        ext = np.maximum(obj.mesh.extents, 1e-3)
        dh = rng.uniform(0.3, 1.0) * max_scale * rng.choice([-1.0, 1.0])
        sz = max(0.5, (ext[2] + dh) / ext[2])
        sxy = rng.uniform(0.9, 1.1, 2)
        return Variation(obj.name, "scale", scale=(sxy[0], sxy[1], sz))
    if kind == "move":
        ang = rng.uniform(0, 2 * np.pi)
        r = rng.uniform(0.3, 1.0) * max_move
        return Variation(obj.name, "move", translation=(r * np.cos(ang), r * np.sin(ang), 0.0),
                         yaw=float(np.deg2rad(rng.uniform(-10, 10))))
    names = sorted(library)
    return Variation(obj.name, "replace", replacement=str(rng.choice(names)))
