"""Motion quality figures, one definition each (synthetic data, augmentation, later the sampler):
bone lengths, foot skate, penetration, joint centres inside objects, grasp distance.

Two depth figures, not to be confused:
- ``penetration_max_cm``: how deep the *body* (the skin around each joint, radii of
  ``trumans.contacts.rule``) goes into the scene -- a seated pelvis 8 cm above the seat gives 2 cm.
- ``joint_centre_inside_cm``: how deep a *joint centre* lies inside given objects (0 unless the
  skeleton itself is inside) -- the augmentation's test that a variation did not swallow a limb.
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np
import trimesh

from trumans.scenes.distance import SceneDistance
from trumans.scenes.scene import Scene

from trumans.intervals import run_bounds
from trumans.contacts.rule import body_penetration
from trumans.skeleton import FOOT_JOINTS, NUM_JOINTS, bone_lengths

__all__ = [
    "bone_length_dev_mm",
    "foot_slides",
    "foot_skate_cm",
    "foot_skate_planted_cm",
    "penetration_depth",
    "penetration_max_cm",
    "joint_centre_inside_cm",
    "grasp_dist_cm",
]


def _check_joints(joints: np.ndarray) -> np.ndarray:
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {joints.shape}")
    return joints


def bone_length_dev_mm(joints: np.ndarray, offsets: np.ndarray) -> float:
    """Max |bone length - the actor's bone length| over frames and bones, in mm.

    joints: (T, 24, 3) m; offsets: (24, 3) the actor's rest offsets (m) — its bone lengths are
    ``|offsets[1:]|``."""
    joints = _check_joints(joints)
    offsets = np.asarray(offsets, dtype=np.float64)
    if offsets.shape != (NUM_JOINTS, 3):
        raise ValueError(f"offsets must be (24, 3), got {offsets.shape}")
    ref = np.linalg.norm(offsets[1:], axis=-1)
    return float(np.abs(bone_lengths(joints) - ref).max() * 1000.0) if len(joints) else 0.0


def foot_slides(foot: np.ndarray, contact: np.ndarray) -> np.ndarray:
    """Horizontal slide of each foot contact run ("step"), metres.

    foot: (T, F, 3) foot joint positions (m); contact: (T, F) bool floor contact of each foot.
    A step is a maximal run of consecutive contact frames of one foot; its slide is the horizontal
    path length of the foot joint over the run. Returns (n_steps,) float64."""
    foot = np.asarray(foot, dtype=np.float64)
    contact = np.asarray(contact, dtype=bool)
    if foot.ndim != 3 or foot.shape[-1] != 3 or contact.shape != foot.shape[:2]:
        raise ValueError(f"foot must be (T, F, 3) and contact (T, F); got {foot.shape} and {contact.shape}")
    out = []
    step = np.linalg.norm(np.diff(foot[..., :2], axis=0), axis=-1)  # (T-1, F) per-frame horizontal move
    both = contact[1:] & contact[:-1]  # the foot is in contact at both ends of the frame step
    for f in range(foot.shape[1]):
        starts, ends = run_bounds(contact[:, f])  # run = frames [s, e)
        if len(starts) == 0:
            continue
        cum = np.concatenate([[0.0], np.cumsum(np.where(both[:, f], step[:, f], 0.0))])
        out.append(cum[ends - 1] - cum[starts])
    return np.concatenate(out) if out else np.zeros(0)


def foot_skate_cm(foot: np.ndarray, contact: np.ndarray) -> float:
    """Mean horizontal slide of a foot while in floor contact, per step, in cm (see ``foot_slides``)."""
    s = foot_slides(foot, contact)
    return float(s.mean() * 100.0) if len(s) else 0.0


def foot_skate_planted_cm(J: np.ndarray, Jc: np.ndarray, fps: float) -> float:
    """Mean horizontal slide (cm) of the foot joints (ankles, toe bases) of J (T, 24, 3) m over the
    planted runs of the truth Jc (T, 24, 3) m at ``fps``: a foot joint under 0.1 m/s and within 5 cm
    of its lowest in the clip. NaN where the truth has no planted run."""
    feet = Jc[:, list(FOOT_JOINTS)]
    speed = np.linalg.norm(np.gradient(feet[..., :2], axis=0), axis=-1) * fps
    planted = (speed < 0.1) & (feet[..., 2] - feet[..., 2].min(0) < 0.05)
    s = foot_slides(J[:, list(FOOT_JOINTS)], planted)
    return float(100 * s.mean()) if len(s) else float("nan")


def penetration_depth(signed: np.ndarray, facing: np.ndarray | None = None) -> np.ndarray:
    """Body penetration per joint, metres (T, 24): ``trumans.contacts.rule.body_penetration``.

    signed: (T, 24) signed distance of each joint centre to the nearest scene surface (m, negative
    inside; ``ContactResult.distance``); facing: (T, 24) bool ``ContactResult.facing``. The body
    around joint j is the ball of ``JOINT_CORE_RADIUS[j]`` extended to ``JOINT_RADIUS[j]`` towards
    its outward contact directions (pelvis 0.10 m to the buttocks, foot 0.04 m to the sole, wrist
    0.03 m to the palm, ...), so a seated pelvis 0.08 m above the seat penetrates 2 cm and a joint
    centre inside an object penetrates by its contact radius + its depth."""
    return body_penetration(signed, facing)


def penetration_max_cm(penetration: np.ndarray) -> float:
    """Deepest body penetration into the scene (static meshes, objects at their per-frame poses,
    and the floor), over all frames and joints, in cm. penetration: (T, 24) m from
    ``penetration_depth`` / ``ContactResult.penetration``. Seated and lying contacts are included:
    the pelvis/back joints are measured against the seat/bed like any other surface."""
    d = np.asarray(penetration, dtype=np.float64)
    return float(d.max() * 100.0) if d.size else 0.0


# SceneDistance of an object's mesh in its own frame, by mesh content (vertices and faces): a moved
# object, or the same replacement placed again, is tested with the bodies and the ray-casting scene
# already built; least recently used dropped first
_LOCAL_DISTANCE: OrderedDict[bytes, SceneDistance] = OrderedDict()
_LOCAL_DISTANCE_SIZE = 64


def _local_distance(mesh: trimesh.Trimesh) -> SceneDistance:
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    key = hashlib.blake2b(v.tobytes() + b"|" + f.tobytes(), digest_size=16).digest()
    sd = _LOCAL_DISTANCE.get(key)
    if sd is None:
        sd = _LOCAL_DISTANCE[key] = SceneDistance({"object": mesh}, build_scene=False)
        while len(_LOCAL_DISTANCE) > _LOCAL_DISTANCE_SIZE:
            _LOCAL_DISTANCE.popitem(last=False)
    else:
        _LOCAL_DISTANCE.move_to_end(key)
    return sd


def _is_rigid(pose: np.ndarray) -> bool:
    R = pose[:3, :3]
    return bool(np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.allclose(pose[3], [0, 0, 0, 1]))


def joint_centre_inside_cm(joints: np.ndarray, scene: Scene, names: list[str]) -> float:
    """Deepest joint centre inside the objects ``names`` of ``scene`` (objects at their scene
    poses), cm; 0 if no joint centre is inside. joints: (T, 24, 3) m world. Unlike
    ``penetration_max_cm`` this ignores the body's thickness (module doc).

    Computed in each object's own frame (inside-ness and distances do not change under its rigid
    pose), with the object's bodies and ray-casting scene cached by mesh content; a joint inside
    any of the objects counts with its distance to the nearest of their surfaces."""
    joints = _check_joints(joints)
    unknown = [n for n in names if n not in scene.objects]
    if unknown:
        raise ValueError(f"objects {unknown} are not in scene {scene.name!r}; it has {sorted(scene.objects)}")
    if not names:
        return 0.0
    pts = joints.reshape(-1, 3)
    objs = [scene.objects[n] for n in names]
    if not all(_is_rigid(o.pose) for o in objs):
        return _joint_centre_inside_world_cm(pts, {n: o.world_mesh() for n, o in zip(names, objs)})
    local, near = [], np.zeros(len(pts), bool)
    for o in objs:
        inv = np.linalg.inv(o.pose)
        q = pts @ inv[:3, :3].T + inv[:3, 3]
        lo, hi = o.mesh.bounds  # only joints inside an object's box can be inside the object
        near |= np.all((q >= lo) & (q <= hi), axis=1)
        local.append(q)
    if not near.any():
        return 0.0
    # inside test first; the closest points only for the joints found inside
    inside = np.zeros(int(near.sum()), bool)
    for o, q in zip(objs, local):
        inside |= _local_distance(o.mesh).inside_per_mesh(np.ascontiguousarray(q[near], dtype=np.float32))[:, 0]
    if not inside.any():
        return 0.0
    depth = np.full(int(inside.sum()), np.inf)
    for o, q in zip(objs, local):
        d = _local_distance(o.mesh).query(np.ascontiguousarray(q[near][inside], dtype=np.float32)).dist
        depth = np.minimum(depth, d)
    return float(depth.max() * 100.0)


def _joint_centre_inside_world_cm(pts: np.ndarray, meshes: dict[str, trimesh.Trimesh]) -> float:
    """``joint_centre_inside_cm`` on world meshes (objects with a pose that is not rigid)."""
    near = np.zeros(len(pts), bool)
    for m in meshes.values():
        lo, hi = m.bounds
        near |= np.all((pts >= lo) & (pts <= hi), axis=1)
    if not near.any():
        return 0.0
    sd = SceneDistance(meshes, build_scene=False)
    q = np.ascontiguousarray(pts[near], dtype=np.float32)
    inside = sd.inside_per_mesh(q).any(-1)
    if not inside.any():
        return 0.0
    s = sd.query(q[inside]).signed
    return float(max(0.0, -float(s.min())) * 100.0)


def grasp_dist_cm(gaps: np.ndarray) -> float:
    """Mean hand-to-object-surface distance on grasp frames, cm. gaps: (n,) metres, one per
    (frame, grasping hand): the distance from the hand's palm point (midpoint of wrist and index1,
    ``trumans.synth.hands.palm_points``) to the surface of the object it holds."""
    g = np.asarray(gaps, dtype=np.float64).ravel()
    return float(g.mean() * 100.0) if g.size else 0.0
