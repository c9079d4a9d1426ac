"""Per-joint contact labels from geometry: the TRUMANS contact rule (appendix B.6) applied to joints.

TRUMANS labels a body *vertex* in contact if (i) it lies inside an object's mesh, or (ii) it lies
within a threshold distance of the object and the angle between its normal and the direction
towards the object is under 60 degrees. Joints lie *inside* the body, so each joint ``j`` carries
(conventions owned here):

- a body-surface radius ``JOINT_RADIUS[j]`` (m): the distance from the joint to the skin that
  touches things (pelvis -> buttocks 0.10 m, foot joint -> sole 0.04 m, wrist -> palm 0.03 m, ...);
  the skin point is modelled as the sphere of that radius around the joint;
- a few outward directions (unit, world) computed from the pose: the body's back / down for the
  torso, world down for the feet, the palm normal and the finger axis for the hands;
- a core radius ``JOINT_CORE_RADIUS[j]`` <= the contact radius: the body's thickness around the
  joint in the other directions (the ankle's sides are closer than its heel).

The body around joint j is thus the ball of the core radius, extended to the contact radius within
60 deg of an outward direction. Its penetration into the scene is
``max(0, r_eff - s)`` with ``r_eff`` the contact radius if the closest surface point lies in
that cone (or the joint centre is inside a solid), else the core radius.

Rule, with ``s`` the signed distance of the joint centre to the nearest surface (negative inside):
``contact = penetration > 0`` (the body around the joint is inside the object: rule (i))
``or (s < r + threshold and facing)``, where *facing* means the angle between one of the joint's
outward directions and the direction from the joint to the closest surface point is under 60 deg
(rule (ii)). The floor (the plane z = 0) counts as an object, so planted feet are in contact.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from trumans.scenes.distance import DistanceResult, SceneDistance
from trumans.scenes.scene import Scene

from trumans.rotations import unit
from trumans.skeleton import INDEX1, JOINT_INDEX, KNEES, NUM_JOINTS, SEAT, WRISTS

__all__ = [
    "JOINT_RADIUS",
    "JOINT_CORE_RADIUS",
    "body_penetration",
    "FACING_COS",
    "CONTACT_THRESHOLD",
    "HOLD_THRESHOLD",
    "FLOOR_NAME",
    "ContactResult",
    "ContactScene",
    "outward_directions",
    "contact_rule",
    "joint_contacts",
]

FACING_COS = 0.5  # cos(60 deg), TRUMANS appendix B.6
CONTACT_THRESHOLD = 0.02  # m beyond the body surface (TRUMANS leaves the value open; 2 cm)
# m beyond the body surface within which the augmentation holds a joint to its surface: wider than
# CONTACT_THRESHOLD so that near-contacts the labels leave out (a hand hovering on a handle) still
# follow a changed object instead of drifting off it.
HOLD_THRESHOLD = 0.03
FLOOR_NAME = "floor_plane"

_RADIUS = {
    "pelvis": 0.10, "left_hip": 0.08, "right_hip": 0.08, "spine1": 0.10, "left_knee": 0.05,
    "right_knee": 0.05, "spine2": 0.10, "left_ankle": 0.085, "right_ankle": 0.085, "spine3": 0.10,
    "left_foot": 0.04, "right_foot": 0.04, "neck": 0.06, "left_collar": 0.06, "right_collar": 0.06,
    "head": 0.09, "left_shoulder": 0.05, "right_shoulder": 0.05, "left_elbow": 0.04,
    "right_elbow": 0.04, "left_wrist": 0.03, "right_wrist": 0.03, "left_index1": 0.015,
    "right_index1": 0.015,
}
# (24,) float64, m: distance from each joint to the body surface that makes contact.
JOINT_RADIUS: np.ndarray = np.array([_RADIUS[n] for n in JOINT_INDEX], dtype=np.float64)
_CORE = {
    "pelvis": 0.09, "left_hip": 0.06, "right_hip": 0.06, "spine1": 0.08, "left_knee": 0.045,
    "right_knee": 0.045, "spine2": 0.08, "left_ankle": 0.035, "right_ankle": 0.035, "spine3": 0.08,
    "left_foot": 0.03, "right_foot": 0.03, "neck": 0.05, "left_collar": 0.05, "right_collar": 0.05,
    "head": 0.08, "left_shoulder": 0.045, "right_shoulder": 0.045, "left_elbow": 0.035,
    "right_elbow": 0.035, "left_wrist": 0.025, "right_wrist": 0.025, "left_index1": 0.012,
    "right_index1": 0.012,
}
# (24,) float64, m: body thickness around each joint in directions that are not outward contact
# directions (e.g. the ankle's sides vs. its heel); <= JOINT_RADIUS.
JOINT_CORE_RADIUS: np.ndarray = np.array([_CORE[n] for n in JOINT_INDEX], dtype=np.float64)

_J = JOINT_INDEX
_TORSO_BACK = [_J[n] for n in ("spine1", "spine2", "spine3", "neck", "left_collar", "right_collar",
                                "head", "left_shoulder", "right_shoulder")]
_SEAT = list(SEAT)
_DOWN = [_J[n] for n in ("left_ankle", "right_ankle", "left_foot", "right_foot", "left_elbow", "right_elbow")]
_KNEES = list(KNEES)
# hand joint -> (side: +1 left / -1 right, the hand's wrist, its index1)
_HANDS = {j: (side, w, i) for side, w, i in ((+1.0, WRISTS[0], INDEX1[0]), (-1.0, WRISTS[1], INDEX1[1])) for j in (w, i)}
_NDIR = 3  # outward directions per joint (unused slots are zero vectors, which never face)


def outward_directions(joints: np.ndarray, global_rot: np.ndarray | None = None) -> np.ndarray:
    """Outward contact directions per joint.

    joints: (T, 24, 3) metres, z-up world; global_rot: optional (T, 24, 3, 3) global joint
    rotations (from FK). Returns (T, 24, 3, 3): up to three unit directions per joint (zero rows
    are unused). Torso joints: the body's backward direction (and for pelvis/hips also the spine's
    downward direction and world down); feet, ankles, elbows: world down; knees: world down and
    body forward; hands: with ``global_rot`` the palm normal (the rest pose is a T-pose with palms
    down, so palm = G_wrist @ -z) and the finger axis, else the wrist->index1 axis and world down.
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {joints.shape}")
    T = joints.shape[0]
    up = unit(joints[:, _J["spine3"]] - joints[:, _J["pelvis"]])  # (T, 3) body up (spine axis)
    left = joints[:, _J["left_hip"]] - joints[:, _J["right_hip"]]
    left = unit(left - (left * up).sum(-1, keepdims=True) * up)
    fwd = np.cross(left, up)  # x = y cross z: (forward, left, up) is right-handed
    down_w = np.broadcast_to(np.array([0.0, 0.0, -1.0]), (T, 3))
    d = np.zeros((T, NUM_JOINTS, _NDIR, 3))
    d[:, _TORSO_BACK, 0] = -fwd[:, None]
    d[:, _SEAT, 0] = -fwd[:, None]
    d[:, _SEAT, 1] = -up[:, None]
    d[:, _SEAT, 2] = down_w[:, None]
    d[:, _DOWN, 0] = down_w[:, None]
    d[:, _KNEES, 0] = down_w[:, None]
    d[:, _KNEES, 1] = fwd[:, None]
    for j, (side, wrist, tip) in _HANDS.items():
        if global_rot is not None:
            R = np.asarray(global_rot)[:, j]
            d[:, j, 0] = R @ np.array([0.0, 0.0, -1.0])  # palm normal
            d[:, j, 1] = R @ np.array([0.0, side, 0.0])  # finger axis (left hand along +y at rest)
        else:
            d[:, j, 0] = unit(joints[:, tip] - joints[:, wrist])
            d[:, j, 1] = down_w
    return d


@dataclass
class ContactResult:
    """Per-joint contacts. contact (T, 24) bool; object_index (T, 24) int64 into ``names`` (-1 = no
    contact); closest (T, 24, 3) closest surface point (world, m); distance (T, 24) signed distance of
    the joint centre to the nearest surface (m, negative inside); names: object names by index;
    facing (T, 24) bool the closest point lies within 60 deg of an outward direction;
    penetration (T, 24) m, how deep the body around the joint is inside the scene (module doc)."""

    contact: np.ndarray
    object_index: np.ndarray
    closest: np.ndarray
    distance: np.ndarray
    names: list[str]
    facing: np.ndarray
    penetration: np.ndarray


def body_penetration(signed: np.ndarray, facing: np.ndarray | None = None) -> np.ndarray:
    """Depth (m) of the body around each joint inside the scene: ``max(0, r_eff - signed)``.

    signed: (T, 24) signed distance of the joint centres to the nearest surface (m, negative
    inside); facing: (T, 24) bool, the nearest surface lies in an outward direction (then
    ``r_eff = JOINT_RADIUS``, else ``JOINT_CORE_RADIUS``); None = contact radius everywhere.
    A joint centre inside a solid always uses the contact radius."""
    s = np.asarray(signed, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] != NUM_JOINTS:
        raise ValueError(f"signed must be (T, 24), got {s.shape}")
    if facing is None:
        r = np.broadcast_to(JOINT_RADIUS, s.shape)
    else:
        r = np.where(np.asarray(facing, dtype=bool) | (s < 0), JOINT_RADIUS, JOINT_CORE_RADIUS)
    return np.maximum(r - s, 0.0)


def contact_rule(
    joints: np.ndarray, res: DistanceResult, threshold: float = CONTACT_THRESHOLD, global_rot: np.ndarray | None = None
) -> ContactResult:
    """Apply the rule of the module doc to a distance query of the joints.

    joints: (T, 24, 3) m; res: DistanceResult with batch shape (T, 24) (e.g. ``ContactScene.query``).
    """
    if threshold < 0:
        raise ValueError(f"threshold must be >= 0 metres, got {threshold}")
    joints = np.asarray(joints, dtype=np.float64)
    if res.signed.shape != joints.shape[:2]:
        raise ValueError(f"distance result has batch shape {res.signed.shape}, expected {joints.shape[:2]}")
    s = res.signed.astype(np.float64)
    to_obj = unit(res.closest.astype(np.float64) - joints)  # (T, 24, 3)
    dirs = outward_directions(joints, global_rot)  # (T, 24, K, 3)
    cos = np.einsum("tjkc,tjc->tjk", dirs, to_obj).max(-1)
    facing = (cos > FACING_COS) | (res.dist < 1e-6)
    depth = body_penetration(s, facing)
    contact = (depth > 0) | ((s < JOINT_RADIUS + threshold) & facing)
    return ContactResult(
        contact=contact,
        object_index=np.where(contact, res.mesh_index, -1).astype(np.int64),
        closest=res.closest.astype(np.float32),
        distance=s.astype(np.float32),
        names=list(res.names),
        facing=facing,
        penetration=depth.astype(np.float32),
    )


def _floor_result(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance, closest point and normal of the floor plane z = 0 (inside below it)."""
    closest = points.copy()
    closest[..., 2] = 0.0
    normal = np.zeros_like(points)
    normal[..., 2] = 1.0
    return points[..., 2].copy(), closest, normal


def _merge(best: dict, signed, dist, closest, normal, inside, index, mask=None) -> None:
    """Keep, per point, the source with the smallest signed distance (most inside first)."""
    better = signed < best["signed"]
    if mask is not None:
        better &= mask
    best["signed"] = np.where(better, signed, best["signed"])
    best["dist"] = np.where(better, dist, best["dist"])
    best["closest"] = np.where(better[..., None], closest, best["closest"])
    best["normal"] = np.where(better[..., None], normal, best["normal"])
    best["index"] = np.where(better, index, best["index"])
    best["inside"] |= inside if mask is None else (inside & mask)


class ContactScene:
    """Distance queries against a Scene whose dynamic objects move over time.

    Static meshes and non-dynamic objects are queried in world frame; each dynamic object is
    queried in its own frame (points mapped by the inverse of its per-frame pose), so a carried
    cup or an opening door is where the motion put it. The floor plane z = 0 is an extra object
    named ``FLOOR_NAME`` (when ``floor``). ``names`` = static names, then dynamic object names,
    then the floor. ``margin`` (m): dynamic objects are only queried for points within this
    distance of their bounding box (others cannot be in contact or penetrate).
    """

    def __init__(self, scene: Scene, floor: bool = True, margin: float = 0.5) -> None:
        static: dict[str, trimesh.Trimesh] = dict(scene.static)
        static.update({n: o.world_mesh() for n, o in scene.objects.items() if not o.dynamic})
        self.static = SceneDistance(static) if static else None
        self.dynamic = {n: SceneDistance({n: o.mesh}) for n, o in scene.objects.items() if o.dynamic}
        self._bounds = {n: np.asarray(o.mesh.bounds) for n, o in scene.objects.items() if o.dynamic}
        self.default_pose = {n: scene.objects[n].pose for n in self.dynamic}
        self.floor = floor
        self.margin = margin
        self.names: list[str] = list(static) + list(self.dynamic) + ([FLOOR_NAME] if floor else [])

    def query(self, points: np.ndarray, object_poses: dict[str, np.ndarray] | None = None) -> DistanceResult:
        """points: (T, N, 3) world m; object_poses: name -> (T, 4, 4) world-from-object (missing
        dynamic objects stay at their scene pose). Returns a DistanceResult of batch shape (T, N)
        with ``mesh_index`` into ``self.names`` (the source nearest in signed distance)."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 3 or p.shape[-1] != 3:
            raise ValueError(f"points must be (T, N, 3), got {p.shape}")
        T, N = p.shape[:2]
        object_poses = object_poses or {}
        unknown = set(object_poses) - set(self.dynamic)
        if unknown:
            raise ValueError(f"object_poses names {sorted(unknown)} are not dynamic objects of the scene "
                             f"({sorted(self.dynamic)})")
        best = {"signed": np.full((T, N), np.inf), "dist": np.full((T, N), np.inf),
                "closest": np.zeros((T, N, 3)), "normal": np.zeros((T, N, 3)),
                "index": np.full((T, N), -1, np.int64), "inside": np.zeros((T, N), bool)}
        k = 0
        if self.static is not None:
            r = self.static.query(p)
            _merge(best, r.signed, r.dist, r.closest, r.normal, r.inside, r.mesh_index)
            k = len(self.static.names)
        for name, sd in self.dynamic.items():
            pose = np.asarray(object_poses.get(name, self.default_pose[name]), dtype=np.float64)
            pose = np.broadcast_to(pose, (T, 4, 4))
            if not np.isfinite(pose).all():
                raise ValueError(f"object_poses[{name!r}] contains NaN/inf; hold unknown poses at the last known one")
            inv = np.linalg.inv(pose)
            local = np.einsum("tij,tnj->tni", inv[:, :3, :3], p) + inv[:, None, :3, 3]
            lo, hi = self._bounds[name]
            near = np.all((local > lo - self.margin) & (local < hi + self.margin), axis=-1)
            if near.any():
                r = sd.query(local[near])
                R = pose[:, :3, :3][np.nonzero(near)[0]]  # (n, 3, 3)
                t = pose[:, :3, 3][np.nonzero(near)[0]]
                signed = np.full((T, N), np.inf)
                dist = np.full((T, N), np.inf)
                closest = np.zeros((T, N, 3))
                normal = np.zeros((T, N, 3))
                inside = np.zeros((T, N), bool)
                signed[near], dist[near], inside[near] = r.signed, r.dist, r.inside
                closest[near] = np.einsum("nij,nj->ni", R, r.closest) + t
                normal[near] = np.einsum("nij,nj->ni", R, r.normal)
                _merge(best, signed, dist, closest, normal, inside, k)
            k += 1
        if self.floor:
            s, c, nrm = _floor_result(p)
            _merge(best, s, np.abs(s), c, nrm, s < 0, k)
        return DistanceResult(
            dist=best["dist"].astype(np.float32), signed=best["signed"].astype(np.float32),
            closest=best["closest"].astype(np.float32), normal=best["normal"].astype(np.float32),
            mesh_index=best["index"], names=list(self.names), inside=best["inside"],
        )


def joint_contacts(
    joints: np.ndarray,
    dist: SceneDistance | ContactScene,
    threshold: float = CONTACT_THRESHOLD,
    global_rot: np.ndarray | None = None,
    object_poses: dict[str, np.ndarray] | None = None,
    floor: bool = True,
) -> ContactResult:
    """Per-joint contact labels (TRUMANS rule, appendix B.6, applied to joints; see module doc).

    joints: (T, 24, 3) float, metres, z-up world; dist: a SceneDistance over world meshes (the
    floor plane z = 0 is added as object ``FLOOR_NAME`` when ``floor``) or a ContactScene (moving
    objects at ``object_poses``, name -> (T, 4, 4)); threshold: contact distance beyond the body
    surface (m); global_rot: optional (T, 24, 3, 3) global joint rotations for palm directions.
    Returns ContactResult with contact (T, 24) bool, object_index (T, 24) (-1 = none),
    closest (T, 24, 3), distance (T, 24) signed (m).
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {joints.shape}")
    if global_rot is not None and np.shape(global_rot) != joints.shape[:2] + (3, 3):
        raise ValueError(f"global_rot must be {joints.shape[:2] + (3, 3)}, got {np.shape(global_rot)}")
    if isinstance(dist, ContactScene):
        res = dist.query(joints, object_poses)
    elif isinstance(dist, SceneDistance):
        if object_poses:
            raise ValueError("object_poses need a ContactScene (built from a Scene), not a SceneDistance")
        r = dist.query(joints)
        names = list(r.names)
        if floor:
            best = {"signed": r.signed.astype(np.float64), "dist": r.dist.astype(np.float64),
                    "closest": r.closest.astype(np.float64), "normal": r.normal.astype(np.float64),
                    "index": r.mesh_index.copy(), "inside": r.inside.copy()}
            s, c, nrm = _floor_result(joints)
            _merge(best, s, np.abs(s), c, nrm, s < 0, len(names))
            names.append(FLOOR_NAME)
            r = DistanceResult(best["dist"].astype(np.float32), best["signed"].astype(np.float32),
                               best["closest"].astype(np.float32), best["normal"].astype(np.float32),
                               best["index"], names, best["inside"])
        res = r
    else:
        raise ValueError(f"dist must be a SceneDistance or ContactScene, got {type(dist).__name__}")
    return contact_rule(joints, res, threshold, global_rot)
