"""Small synthetic interaction clips with exact contacts, for the augmentation tests and benchmark.

Each case is a (Sequence, Scene) pair at 30 fps built from keyframe poses (trumans.synth.poses),
procedural furniture (trumans.scenes.furniture) and analytic limb IK, with both feet planted on the
floor whenever the person stands or sits. Kinds (CASE_KINDS): ``sit`` (sit down on a chair, sit,
stand up), ``lie`` (lying on a bed, arms moving), ``hand`` (one hand placed on a table and lifted
again), ``two_hands`` (both hands on a table), ``successive`` (right hand on the table, then the
left hand as the right one leaves). A different seed gives a different actor, furniture and timing.
"""
from __future__ import annotations

import numpy as np
import trimesh

from trumans.scenes import furniture
from trumans.scenes.scene import Scene
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, yaw_matrix
from trumans.sequence import Sequence
from trumans.skeleton import JOINT_INDEX, forward_kinematics, rest_offsets
from trumans.ik.limb import solve_limb
from trumans.synth.legs import foot_places, solve_legs, standing_state
from trumans.synth.poses import ease, pose, slerp_rot

__all__ = ["CASE_KINDS", "make_case", "make_cases", "replacement_library"]

CASE_KINDS: tuple[str, ...] = ("sit", "lie", "hand", "two_hands", "successive")
FPS = 30.0
_J = JOINT_INDEX


def _ramp(T: int, keys: list[tuple[int, float]]) -> np.ndarray:
    """(T,) eased piecewise-linear weight through (frame, value) keys."""
    t = np.arange(T)
    fr = np.array([k[0] for k in keys], float)
    val = np.array([k[1] for k in keys], float)
    out = np.interp(t, fr, val)
    # ease each segment: replace linear interpolation by smootherstep between keys
    for (f0, v0), (f1, v1) in zip(keys[:-1], keys[1:]):
        m = (t >= f0) & (t <= f1)
        if f1 > f0:
            out[m] = v0 + (v1 - v0) * ease((t[m] - f0) / (f1 - f0))
    return out


def _sequence(rot: np.ndarray, root: np.ndarray, off: np.ndarray, scene: Scene) -> Sequence:
    P, _ = forward_kinematics(rot, root, off)
    return Sequence(joints=P.astype(np.float32), fps=FPS, rotations=matrix_to_6d(rot).astype(np.float32),
                    root_pos=root.astype(np.float32), scene=scene.name)


def _plant(rot: np.ndarray, root: np.ndarray, off: np.ndarray, feet: np.ndarray, yaw: float) -> np.ndarray:
    T = len(rot)
    frot = np.broadcast_to(yaw_matrix(yaw), (T, 2, 3, 3))
    rot, _ = solve_legs(rot, root, off, np.broadcast_to(feet, (T, 2, 3)), foot_rot=frot)
    return rot


def _sit(rng: np.random.Generator, off: np.ndarray) -> tuple[Sequence, Scene]:
    chair = furniture.chair(rng, "chair")
    chair.dynamic, chair.dof = False, "static"
    h = chair.meta["seat_height"]
    seat_x = chair.meta["seat_center"][0]
    stand_pos = np.array([chair.mesh.bounds[1, 0] + rng.uniform(0.22, 0.28), 0.0])
    feet = foot_places(off, stand_pos, 0.0)
    rs, root_s = standing_state(off, stand_pos, 0.0)
    sit = pose("sit", off)
    root_sit = np.array([seat_x + 0.02, 0.0, h + 0.095])
    a, b, c = 30, int(rng.integers(70, 80)), int(rng.integers(140, 160))
    d = c + (b - a)
    T = d + 30
    w = _ramp(T, [(0, 0.0), (a, 0.0), (b, 1.0), (c, 1.0), (d, 0.0), (T - 1, 0.0)])
    rot = slerp_rot(np.broadcast_to(rs, (T, 24, 3, 3)), np.broadcast_to(sit, (T, 24, 3, 3)), w[:, None])
    root = root_s + w[:, None] * (root_sit - root_s)
    rot = _plant(rot, root, off, feet, 0.0)
    scene = Scene("toy_sit", objects={"chair": chair})
    return _sequence(rot, root, off, scene), scene


def _lie(rng: np.random.Generator, off: np.ndarray) -> tuple[Sequence, Scene]:
    bed = furniture.bed(rng, "bed")
    hm = bed.meta["lie_center"][2]
    T = int(rng.integers(80, 110))
    lie = pose("lie", off)
    rot = np.broadcast_to(lie, (T, 24, 3, 3)).copy()
    R = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # rest x -> +z (face up), z -> -x
    rot[:, 0] = R
    swing = 0.3 * np.sin(np.linspace(0, 2 * np.pi, T))  # arms sweep in the bed's plane (about body forward)
    for j, sgn in ((_J["left_shoulder"], 1.0), (_J["right_shoulder"], -1.0)):
        rot[:, j] = axis_angle_to_matrix(np.array([sgn, 0.0, 0.0]) * swing[:, None]) @ rot[:, j]
    cx = bed.meta["lie_center"][0] + 0.1
    root = np.tile([cx, 0.0, hm + 0.085], (T, 1))  # the pelvis 8.5 cm above the mattress (its skin on it)
    P, _ = forward_kinematics(rot, root, off)
    root[:, 2] += max(0.0, 0.01 - (P[..., 2] - hm).min())  # no joint closer than 1 cm to the mattress
    scene = Scene("toy_lie", objects={"bed": bed})
    return _sequence(rot, root, off, scene), scene


def _table_case(rng: np.random.Generator, off: np.ndarray, hands: list[tuple[str, int, int]], T: int,
                name: str) -> tuple[Sequence, Scene]:
    table = furniture.table(rng, "table")
    table.dynamic, table.dof = False, "static"
    sx = table.meta["surface_size"][0]
    stand_pos = np.array([sx / 2 + rng.uniform(0.30, 0.36), rng.uniform(-0.1, 0.1)])
    yaw = np.pi
    rs, root0 = standing_state(off, stand_pos, yaw)
    feet = foot_places(off, stand_pos, yaw)
    lean = rs.copy()
    for n, deg in (("spine1", 20.0), ("spine2", 15.0), ("spine3", 10.0)):
        lean[_J[n]] = lean[_J[n]] @ axis_angle_to_matrix(np.array([0.0, np.deg2rad(deg), 0.0]))
    P0, _ = forward_kinematics(lean[None], root0[None], off)
    # a counter-height table: its top is where the palms of the bent torso's arms (at 90 % of
    # their reach, 5-15 cm in front of the shoulders) rest
    arm = np.linalg.norm(off[_J["right_elbow"]]) + np.linalg.norm(off[_J["right_wrist"]])
    sh_x = P0[0, _J["right_shoulder"], 0]
    dx = max(rng.uniform(0.05, 0.15), sh_x - (sx / 2 - 0.06))  # the palm lands on the top, not past its edge
    sh_z = P0[0, _J["right_shoulder"], 2]
    top = sh_z - 0.026 - np.sqrt((0.9 * arm) ** 2 - dx**2 - 0.05**2)
    sz = top / table.meta["surface_height"]
    table.mesh.vertices = np.asarray(table.mesh.vertices) * np.array([1.0, 1.0, sz])
    table.meta = {**table.meta, "surface_height": float(top), "surface_center": [0.0, 0.0, float(top)],
                  "size": [float(x) for x in table.mesh.extents]}
    rot = np.broadcast_to(rs, (T, 24, 3, 3)).copy()
    root = np.tile(root0, (T, 1))
    w_all = np.zeros(T)
    for limb, t0, t1 in hands:
        side = 1.0 if limb == "left_arm" else -1.0
        sh = P0[0, _J["left_shoulder" if side > 0 else "right_shoulder"]]
        # palm on the table top, dx in front of the shoulder (towards -x), 2.6 cm above it
        target = np.array([sh[0] - dx, sh[1] + side * rng.uniform(0.0, 0.05), top + 0.026])
        hold, ok = solve_limb(lean[None], root0[None], off, limb, target)
        if not ok.all():
            raise RuntimeError(f"toy case {name}: the {limb} cannot reach the table (seed too extreme)")
        k = 25
        w = _ramp(T, [(0, 0.0), (max(t0 - k, 0), 0.0), (t0, 1.0), (t1, 1.0), (min(t1 + k, T - 1), 0.0), (T - 1, 0.0)])
        w_all = np.maximum(w_all, w)
        arm = [_J[n] for n in (("left_" if side > 0 else "right_") + p for p in ("collar", "shoulder", "elbow", "wrist"))]
        rot[:, arm] = slerp_rot(rot[:, arm], np.broadcast_to(hold[0, arm], (T, len(arm), 3, 3)), w[:, None])
    spine = [_J["spine1"], _J["spine2"], _J["spine3"]]
    rot[:, spine] = slerp_rot(rot[:, spine], np.broadcast_to(lean[spine], (T, 3, 3, 3)), w_all[:, None])
    rot = _plant(rot, root, off, feet, yaw)
    scene = Scene(f"toy_{name}", objects={"table": table})
    return _sequence(rot, root, off, scene), scene


def make_case(kind: str, seed: int) -> tuple[Sequence, Scene]:
    """One clip of ``kind`` (CASE_KINDS) with its scene; deterministic in ``seed``."""
    if kind not in CASE_KINDS:
        raise ValueError(f"unknown toy case {kind!r}; choose one of {CASE_KINDS}")
    rng = np.random.default_rng(seed)
    off = rest_offsets(rng.uniform(0.94, 1.06))
    if kind == "sit":
        return _sit(rng, off)
    if kind == "lie":
        return _lie(rng, off)
    if kind == "hand":
        t0 = int(rng.integers(40, 50))
        return _table_case(rng, off, [("right_arm", t0, t0 + 50)], t0 + 100, kind)
    if kind == "two_hands":
        t0 = int(rng.integers(40, 50))
        return _table_case(rng, off, [("right_arm", t0, t0 + 50), ("left_arm", t0, t0 + 50)], t0 + 100, kind)
    t0 = int(rng.integers(40, 50))
    return _table_case(rng, off, [("right_arm", t0, t0 + 40), ("left_arm", t0 + 40, t0 + 80)], t0 + 130, kind)


def make_cases(seed: int, per_kind: int = 1) -> list[tuple[str, Sequence, Scene]]:
    """``per_kind`` clips of every kind: [(kind, sequence, scene)]."""
    out = []
    for i in range(per_kind):
        for k, kind in enumerate(CASE_KINDS):
            out.append((kind, *make_case(kind, seed * 1000 + i * len(CASE_KINDS) + k)))
    return out


def replacement_library(category: str, seed: int, n: int = 3, scene: Scene | None = None) -> dict[str, trimesh.Trimesh]:
    """n other instances (object-frame meshes) of a furniture ``category`` ('chair', 'bed', 'table');
    with ``scene``, tables are rescaled to the height of that scene's (counter-height) table."""
    builders = {"chair": furniture.chair, "bed": furniture.bed, "table": furniture.table}
    if category not in builders:
        raise ValueError(f"no replacement builder for category {category!r}; have {sorted(builders)}")
    rng = np.random.default_rng(seed)
    out = {}
    for i in range(n):
        m = builders[category](rng, f"{category}_alt{i}").mesh
        if scene is not None and category == "table" and "table" in scene.objects:
            h = scene.objects["table"].mesh.extents[2] * rng.uniform(0.92, 1.08)
            m.vertices = np.asarray(m.vertices) * np.array([1.0, 1.0, h / m.extents[2]])
        out[f"{category}_alt{i}"] = m
    return out
