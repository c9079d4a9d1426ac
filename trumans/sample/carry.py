"""Dynamic objects after the body: each object the plan handles is moved by the hand that holds it
(TRUMANS §4.2, last paragraph: "we optimize the trajectory of the interacting object ... to
minimize the variance in distance between the object and the interacting hand").

1. ``plan_interactions``: the contact interval of every object step, from the plan's phases (the
   phase whose hand goal is the grasp / handle) refined by the hand: contact starts at the frame
   of that phase where the wrist is closest to its goal (the grasp) and ends at the same frame of
   the put_down phase (the release) or, for open / close, at the end of the moving part.
2. ``optimise_motion``: the object's poses over the interval within its degrees of freedom (free:
   6-DoF rigid; hinge: the angle about its axis; slide: the travel along its axis, or floor xy),
   minimising the variance of the hand's points expressed in the object frame (§4.2) plus the
   squared acceleration of points on the object, with the pose at the grasp fixed to where the
   object rests and, for a carried object, the pose at the release fixed to its put-down pose
   (upright, on the highest support under it: ``put_down_pose``). Door angles and drawer travel
   stay in their range. The initial guess is the iReplica hand-driven motion
   (``trumans.track.objects``: ``free_motion`` / ``hinge_motion`` / ``one_hand_motion``).
3. ``object_tracks``: the whole timeline of every handled object (at rest before, moved during,
   left where released after) as ``ObjectTrack``s for ``Sequence.objects``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch

from trumans.scenes._open3d import open3d_module
from trumans.scenes.raycast import to_o3d_scene
from trumans.track.objects import (dof_limits, dof_value, free_motion, hinge_frame, hinge_motion, one_hand_motion,
                                   rotation_about_axis, rotation_angles)
from trumans.rotations import rodrigues, skew, unit
from trumans.sequence import ObjectTrack
from trumans.skeleton import JOINT_INDEX

__all__ = ["CarryConfig", "Interaction", "hand_track", "plan_interactions", 
           "initial_motion", "optimise_motion", "put_down_pose", "object_tracks"]

InteractionKind = Literal["carry", "open", "close"]


@dataclass(frozen=True)
class CarryConfig:
    """smooth: weight of the squared acceleration (m per frame^2) of points on the object against
    the variance (m^2) of the hand points in the object frame; upright: weight of a free object's
    tilt away from its rest up axis; limit: weight of the penalty beyond a dof limit during the
    optimisation (the result is clipped to the range); iters: L-BFGS iterations; reach_m: the
    wrist must come this close to a grasp point / handle for a contact (else the object stays)."""

    smooth: float = 0.3
    upright: float = 0.05
    limit: float = 100.0
    iters: int = 100
    reach_m: float = 0.25

    def __post_init__(self) -> None:
        if min(self.smooth, self.upright, self.limit) < 0 or self.iters < 1 or not self.reach_m > 0:
            raise ValueError(f"CarryConfig weights must be >= 0 and iters >= 1, got {self}")


@dataclass(frozen=True)
class Interaction:
    """Object ``name`` is moved by joint ``hand`` on frames [start, end] (inclusive: ``start`` is
    the grasp, ``end`` the release); ``kind`` carry / open / close; ``placed``: a carried object
    put down at ``end`` (False: still held when the motion ends)."""

    name: str
    kind: InteractionKind
    hand: str
    start: int
    end: int
    placed: bool = False


def hand_track(joints: np.ndarray, hand: str) -> tuple[np.ndarray, np.ndarray]:
    """joints (T, 24, 3) and a wrist joint name -> (points (T, 2, 3): wrist and index1, m;
    rotations (T, 3, 3): the hand frame, x wrist -> index1, z normal to the forearm-hand plane)."""
    side = hand.split("_")[0]
    if side not in ("left", "right"):
        raise ValueError(f"hand must be left_wrist or right_wrist, got {hand!r}")
    j = np.asarray(joints, np.float64)
    w, i, e = (j[:, JOINT_INDEX[f"{side}_{n}"]] for n in ("wrist", "index1", "elbow"))
    x = unit(i - w)
    z = unit(np.cross(w - e, x))
    return np.stack([w, i], 1), np.stack([x, np.cross(z, x), z], -1)


def plan_interactions(phase: np.ndarray, phases: list, joints: np.ndarray,
                      reach_m: float = 0.25) -> tuple[list[Interaction], list[tuple[str, float]]]:
    """Contact intervals of the object steps (module doc, 1.) in time order. phase: (T,) index into
    ``phases`` per frame (``SampleResult.phase[b]``); joints: (T, 24, 3). A grasp whose wrist never
    comes within ``reach_m`` of the grasp point / handle is no contact: the object stays. Returns
    (interactions, missed: (object name, closest wrist distance m) per unreached grasp)."""
    T = len(phase)
    grasp: dict[str, tuple[int, str]] = {}
    out: list[Interaction] = []
    missed: list[tuple[str, float]] = []

    def closest(i: int) -> tuple[int, float]:
        f = np.flatnonzero(phase == i)
        p = phases[i]
        d = np.linalg.norm(joints[f, JOINT_INDEX[p.hand]] - p.hand_goal, axis=-1)
        return int(f[np.argmin(d)]), float(d.min())

    def take(i: int, name: str, hand: str) -> None:
        f, d = closest(i)
        if d <= reach_m:
            grasp[name] = (f, hand)
        else:
            missed.append((name, d))

    for i, p in enumerate(phases):
        do = p.info.get("do")
        if do is None or not (phase == i).any():
            continue
        name = p.info["object"]
        if do == "pick_up":
            take(i, name, p.hand)
        elif do == "put_down" and name in grasp:
            g, hand = grasp.pop(name)
            out.append(Interaction(name, "carry", hand, g, max(closest(i)[0], g + 1), placed=True))
        elif do in ("open", "close") and p.info.get("part") == 0:
            take(i, name, p.hand)
        elif do in ("open", "close") and name in grasp:
            g, hand = grasp.pop(name)
            out.append(Interaction(name, do, hand, g, max(int(np.flatnonzero(phase == i)[-1]), g + 1)))
    out += [Interaction(n, "carry", h, g, T - 1) for n, (g, h) in grasp.items() if g < T - 1]  # never put down
    return sorted(out, key=lambda it: it.start), missed


def initial_motion(obj, pose0: np.ndarray, hand_pts: np.ndarray, hand_rot: np.ndarray) -> np.ndarray:
    """(n, 4, 4) world poses driven by the hand from ``pose0`` (iReplica supp. §10, reused from
    ``trumans.track.objects``), clipped to the dof limits. hand_pts (n, 2, 3), hand_rot (n, 3, 3)."""
    mid = hand_pts.mean(1)
    if obj.dof == "free":
        return free_motion(hand_rot, mid) @ pose0
    if obj.dof == "hinge":
        axis, point = hinge_frame(obj)
        lo, hi = dof_limits(obj)
        M = hinge_motion(mid, point, axis)
        angle = np.clip(dof_value(obj, pose0) + rotation_angles(M, axis), lo, hi)
        return rotation_about_axis(angle, axis, point) @ obj.pose
    if obj.dof == "slide":
        axis = None if obj.axis is None else obj.pose[:3, :3] @ obj.axis
        M = one_hand_motion(mid, axis)
        if axis is not None:
            lo, hi = dof_limits(obj)
            s = np.clip(dof_value(obj, pose0) + M[:, :3, 3] @ axis, lo, hi)
            M = np.tile(np.eye(4), (len(s), 1, 1))
            M[:, :3, 3] = s[:, None] * axis
            return M @ obj.pose
        return M @ pose0
    raise ValueError(f"object {obj.name!r} is static (dof {obj.dof}); only free, hinge and slide objects move")


def _object_points(obj) -> np.ndarray:
    """(7, 3) object-frame points spanning the mesh (centre and +-half extents) for the smoothness term."""
    lo, hi = obj.mesh.bounds
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    return np.concatenate([c[None], c + np.diag(h), c - np.diag(h)])


def optimise_motion(obj, init: np.ndarray, hand_pts: np.ndarray, fix_end: bool,
                    config: CarryConfig = CarryConfig()) -> np.ndarray:
    """Object poses (n, 4, 4) over a contact interval within ``obj.dof`` (module doc, 2.).

    init: (n, 4, 4) initial world poses, init[0] the resting pose at the grasp (kept), init[-1]
    the put-down pose (kept when ``fix_end``); hand_pts: (n, K, 3) world m."""
    init, hand_pts = np.asarray(init, np.float64), np.asarray(hand_pts, np.float64)
    n = len(init)
    if init.shape != (n, 4, 4) or hand_pts.ndim != 3 or len(hand_pts) != n or n < 2:
        raise ValueError(f"init must be (n, 4, 4) and hand_pts (n, K, 3) with n >= 2, got {init.shape}, {hand_pts.shape}")
    free = torch.ones(n, 1, dtype=torch.float64)
    free[0] = 0.0
    if fix_end:
        free[-1] = 0.0
    H = torch.from_numpy(hand_pts)
    P = torch.from_numpy(_object_points(obj))
    R0, t0 = torch.from_numpy(init[:, :3, :3]), torch.from_numpy(init[:, :3, 3])
    lo, hi = dof_limits(obj)
    if obj.dof == "free":
        params = torch.zeros(n, 6, dtype=torch.float64, requires_grad=True)
        up = torch.from_numpy(init[0, :3, :3].T @ np.array([0.0, 0.0, 1.0]))

        def poses(x):
            x = x * free
            return torch.linalg.matrix_exp(skew(x[:, :3])) @ R0, t0 + x[:, 3:]
    elif obj.dof == "hinge":
        axis, point = (torch.from_numpy(v) for v in hinge_frame(obj))
        base = torch.from_numpy(obj.pose)
        a0 = torch.from_numpy(np.array([dof_value(obj, p) for p in init]))
        params = torch.zeros(n, 1, dtype=torch.float64, requires_grad=True)

        def value(x):
            return a0 + (x * free)[:, 0]

        def poses(x):
            R = rodrigues(axis.expand(n, 3), value(x))
            Rb = R @ base[:3, :3]
            return Rb, (R @ (base[:3, 3] - point)[:, None])[..., 0] + point
    elif obj.dof == "slide" and obj.axis is not None:
        axis = torch.from_numpy(obj.pose[:3, :3] @ obj.axis)
        s0 = torch.from_numpy(np.array([dof_value(obj, p) for p in init]))
        params = torch.zeros(n, 1, dtype=torch.float64, requires_grad=True)

        def value(x):
            return s0 + (x * free)[:, 0]

        def poses(x):
            return R0, torch.from_numpy(obj.pose[:3, 3]) + value(x)[:, None] * axis
    elif obj.dof == "slide":
        params = torch.zeros(n, 2, dtype=torch.float64, requires_grad=True)

        def poses(x):
            x = x * free
            return R0, t0 + torch.cat([x, torch.zeros(n, 1, dtype=x.dtype)], 1)
    else:
        raise ValueError(f"object {obj.name!r} is static (dof {obj.dof}); only free, hinge and slide objects move")

    def loss():
        R, t = poses(params)
        q = torch.einsum("nji,nkj->nki", R, H - t[:, None])  # hand points in the object frame
        var = ((q - q.mean(0)) ** 2).sum(-1).mean()  # §4.2: variance of the hand-object offset
        X = torch.einsum("nij,pj->npi", R, P) + t[:, None]
        acc = ((X[2:] - 2 * X[1:-1] + X[:-2]) ** 2).sum(-1).mean() if n > 2 else var * 0
        total = var + config.smooth * acc
        if obj.dof == "free":
            total = total + config.upright * ((1.0 - (R @ up)[:, 2]) ** 2).mean()
        elif obj.dof in ("hinge", "slide") and obj.axis is not None and np.isfinite(lo):
            v = value(params)
            total = total + config.limit * (torch.relu(v - hi) ** 2 + torch.relu(lo - v) ** 2).mean()
        return total

    opt = torch.optim.LBFGS([params], lr=1.0, max_iter=config.iters, line_search_fn="strong_wolfe")

    def closure():
        opt.zero_grad()
        f = loss()
        f.backward()
        return f

    opt.step(closure)
    with torch.no_grad():
        if obj.dof in ("hinge", "slide") and obj.axis is not None and np.isfinite(lo):  # stay in range
            v = value(params).clamp(lo, hi)
            base_v = a0 if obj.dof == "hinge" else s0
            params[:, 0] = torch.where(free[:, 0] > 0, v - base_v, params[:, 0])
        R, t = poses(params)
    out = np.tile(np.eye(4), (n, 1, 1))
    out[:, :3, :3], out[:, :3, 3] = R.numpy(), t.numpy()
    return out


def put_down_pose(obj, pose: np.ndarray, supports: list) -> np.ndarray:
    """(4, 4) where a carried object lands when released at ``pose``: turned upright about its rest
    up axis (keeping its heading), lowered or raised onto the highest surface of the ``supports``
    meshes (world frame) under its footprint, or the floor (z = 0)."""
    R_rest = obj.pose[:3, :3]
    yaw = np.arctan2(pose[1, 0], pose[0, 0]) - np.arctan2(R_rest[1, 0], R_rest[0, 0])
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.eye(4)
    out[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R_rest
    out[:3, 3] = pose[:3, 3]
    v = np.asarray(obj.mesh.vertices) @ out[:3, :3].T + out[:3, 3]
    lo, hi = v.min(0), v.max(0)
    xy = np.array([[x, y] for x in np.linspace(lo[0], hi[0], 3) for y in np.linspace(lo[1], hi[1], 3)])
    top = hi[2] + 0.3
    ground = 0.0
    if supports:
        rc, _ = to_o3d_scene(*supports)
        rays = np.concatenate([xy, np.full((len(xy), 1), top), np.tile([0.0, 0.0, -1.0], (len(xy), 1))], 1)
        hit = rc.cast_rays(open3d_module().core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
        z = top - hit[np.isfinite(hit)]
        ground = max(ground, float(z.max())) if len(z) else ground
    out[2, 3] += ground - lo[2]
    return out


def object_tracks(joints: np.ndarray, phase: np.ndarray, phases: list, scene,
                  config: CarryConfig = CarryConfig()) -> tuple[dict[str, ObjectTrack], list[Interaction], dict]:
    """Tracks (T, 4, 4) of every object the plan handles (module doc, 3.) for one sample.

    Returns (name -> ObjectTrack, the interactions, {"init": name -> [(start, (n, 4, 4))] the
    hand-driven initial poses of each interval, "missed": [(name, closest wrist distance m)] the
    grasps the body did not reach}, for the figures)."""
    joints = np.asarray(joints, np.float64)
    T = len(joints)
    its, missed = plan_interactions(phase, phases, joints, config.reach_m)
    tracks: dict[str, np.ndarray] = {}
    inits: dict = {}
    for it in its:
        obj = scene.objects[it.name]
        track = tracks.setdefault(it.name, np.tile(obj.pose, (T, 1, 1)))
        s, e = it.start, it.end
        pts, rot = hand_track(joints[s:e + 1], it.hand)
        init = initial_motion(obj, track[s], pts, rot)
        init[0] = track[s]
        fix_end = it.placed
        if fix_end:
            supports = list(scene.static.values()) + [o.world_mesh(tracks[n][e] if n in tracks else None)
                                                      for n, o in scene.objects.items() if n != it.name]
            init[-1] = put_down_pose(obj, init[-1], supports)
        poses = optimise_motion(obj, init, pts, fix_end, config)
        track[s:e + 1] = poses
        track[e + 1:] = poses[-1]
        inits.setdefault(it.name, []).append((s, init))
    return ({n: ObjectTrack(p.astype(np.float32), scene.objects[n].category) for n, p in tracks.items()}, its,
            {"init": inits, "missed": missed})
