"""Scenes fitted to real motion: a seat under every seated pelvis, a bed under a raised lying body,
a table under a resting hand (``fit_tables``).

Seats stand on the floor (category "seat", ``trumans.scenes.furniture`` frame conventions: origin at the
footprint centre on the floor, +x = the direction the sitter faces). From the seated run of
frames (``trumans.motion_labels``): the facing direction is the mean horizontal thigh direction;
the seat top is ``SEAT_BELOW_HIP_M`` under the hip joints (their ``SEAT_HIP_PERCENTILE``-th
percentile height over the run); the seat reaches ``SEAT_BEHIND_HIP_M`` behind the hips and
``SEAT_THIGH_SHARE`` of the thigh length in front of them, and is the hip width plus
``SEAT_SIDE_M`` on each side wide; it is a top on four legs (the feet of a sitter on a high
stool go under it). A lying body whose pelvis rests
more than ``BED_MIN_HEIGHT_M`` above the floor gets a bed box under it; lower ones lie on the floor.
``fit_scene`` keeps one object per place (a seat sat on twice) and drops a fitted object the
body passes through at other times (``in_the_way``).
"""
from __future__ import annotations

import numpy as np
import trimesh

from trumans.scenes.furniture import GAP, yaw_pose
from trumans.scenes.scene import Scene, SceneObject

from .motion_labels import MOTION_STATES, segments
from .skeleton import JOINT_INDEX as J

__all__ = ["box_object", "fit_seats", "fit_beds", "fit_tables", "fit_scene", "in_the_way", "fitted_contacts", "SEAT_BELOW_HIP_M"]

SEAT_BELOW_HIP_M = 0.10  # hip joint centres sit this far above the seat surface (soft tissue + pelvis)
SEAT_BEHIND_HIP_M = 0.12
SEAT_THIGH_SHARE = 0.75
SEAT_SIDE_M = 0.10
SEAT_MIN_FRONT_M = 0.10  # m, a seat cut back for the limbs still reaches this far in front of the hips
MIN_SEAT_M = 0.20  # lower "seats" are the floor (or a crouch)
SEAT_TOP_M = 0.05  # m, thickness of a fitted seat's top
SEAT_LEG_M = 0.04  # m, side of a fitted seat's square legs
LEG_CLEAR_M = 0.04  # m, a leg this close to a joint's path is left out (about an ankle's core radius)
SEAT_HIP_PERCENTILE = 10  # the seat top follows the lower hip heights of the run (slouching sinks in)
TABLE_MIN_S = 1.0  # s a hand rests for a table to be fitted under it
HAND_STILL_MPS = 0.05  # m/s, wrist speed (0.25 s mean) below which a hand rests
WRIST_ABOVE_TOP_M = 0.03  # m, wrist joint centre above the surface a hand rests on
TABLE_HEIGHT_M = (0.55, 1.10)  # m, the table tops fitted (coffee tables and lower are not told from laps)
TABLE_KNEE_CLEAR_M = 0.12  # m, a table top clears the knees by this much
TABLE_REACH_M = 0.25  # m, a resting hand this far in front of the pelvis (not at the side, on the hip)
TABLE_SIZE_M = (0.6, 0.9)  # m, depth (away from the body) and width of a fitted table
TABLE_EDGE_M = 0.12  # m, the resting hand this far inside the table's near edge
SAME_PLACE_M = 0.25  # m, fits this close (centre, height) are one seat / bed used again
TRANSITION_S = 3.0  # s around a fitted run where the body sits down / gets up (may touch the object)
IN_THE_WAY_S = 0.5  # s of other frames with a joint inside a fitted object that disqualify it
TORSO_INSIDE_S = 0.1  # s of frames (transitions included) with the torso inside a fitted object that disqualify it
TORSO_JOINTS = tuple(J[n] for n in ("pelvis", "left_hip", "right_hip", "spine1", "spine2", "spine3"))
BED_MIN_HEIGHT_M = 0.30
BED_BELOW_BODY_M = 0.08


def box_object(name: str, category: str, x: float, y: float, yaw: float, depth: float, width: float,
               height: float, meta: dict, legs: bool = False, avoid: np.ndarray | None = None) -> SceneObject:
    """A box (depth, width, height) m standing on the floor; with ``legs`` a top of ``SEAT_TOP_M``
    on four ``SEAT_LEG_M`` square legs at its corners (feet tucked under a stool stay free), the
    legs ``GAP`` under the top (disjoint parts that share no vertex stay watertight bodies for the
    inside tests of ``trumans.scenes.distance``; touching ones merge into one open body that is not). A leg
    within ``LEG_CLEAR_M`` of a point of ``avoid`` (N, 3) world m (the body's joints) is left out
    (meta "legs" counts the rest)."""
    pose = yaw_pose(x, y, yaw)
    if legs and height > SEAT_TOP_M + 0.05:
        top = trimesh.creation.box(extents=(depth, width, SEAT_TOP_M))
        top.apply_translation((0.0, 0.0, height - SEAT_TOP_M / 2))
        h = height - SEAT_TOP_M - GAP
        pts = np.zeros((0, 3)) if avoid is None else np.asarray(avoid, np.float64).reshape(-1, 3)
        local = (pts - pose[:3, 3]) @ pose[:3, :3]  # object frame
        local = local[local[:, 2] < h + LEG_CLEAR_M]
        parts = [top]
        for sx in (-1, 1):
            for sy in (-1, 1):
                c = np.array([sx * (depth - SEAT_LEG_M) / 2, sy * (width - SEAT_LEG_M) / 2])
                if (np.abs(local[:, :2] - c).max(axis=1) < SEAT_LEG_M / 2 + LEG_CLEAR_M).any():
                    continue  # the body passes here
                leg = trimesh.creation.box(extents=(SEAT_LEG_M, SEAT_LEG_M, h))
                leg.apply_translation((c[0], c[1], h / 2))
                parts.append(leg)
        mesh = trimesh.util.concatenate(parts)
        meta = {**meta, "legs": len(parts) - 1}
    else:
        mesh = trimesh.creation.box(extents=(depth, width, height))
        mesh.apply_translation((0.0, 0.0, height / 2))
    meta = {"size": [depth, width, height], **meta}
    return SceneObject(name, category, mesh, pose=pose, meta=meta)


def _front_clear(limbs: np.ndarray, hip_mid: np.ndarray, fwd: np.ndarray, front: float, width: float,
                 height: float) -> float:
    """The seat front (m ahead of the hips, at most ``front``) that keeps ``LEG_CLEAR_M`` from every
    limb point (N, 3) m within ``LEG_CLEAR_M`` of its top slab (a seat of ``width`` facing ``fwd``)."""
    rel = limbs[:, :2] - hip_mid[:2]
    x, y = rel @ fwd, rel @ np.array([-fwd[1], fwd[0]])
    z = limbs[:, 2]
    near = (np.abs(y) < width / 2 + LEG_CLEAR_M) & (z > height - SEAT_TOP_M - LEG_CLEAR_M) & \
        (z < height + LEG_CLEAR_M) & (x > SEAT_MIN_FRONT_M) & (x < front + LEG_CLEAR_M)
    return float(np.clip(x[near].min(initial=np.inf) - LEG_CLEAR_M, SEAT_MIN_FRONT_M, front))


def fit_seats(joints: np.ndarray, states: np.ndarray, fps: float = 30.0, min_seconds: float = 1.0) -> list[SceneObject]:
    """One seat box per seated run (>= ``min_seconds``) of joints (T, 24, 3) m with per-frame
    ``states`` (indices into ``MOTION_STATES``); runs seated on the floor get none. The seat's front
    is cut back (not nearer than ``SEAT_MIN_FRONT_M`` to the hips) where a limb joint of any frame
    would be in its top (a foot pulled up to the edge, a knee of legs dangling from a high stool)."""
    j = np.asarray(joints, np.float64)
    limbs = j[:, [k for k in range(j.shape[1]) if k not in TORSO_JOINTS]].reshape(-1, 3)
    out = []
    for s, e in segments(np.asarray(states) == MOTION_STATES.index("sit")):
        if e - s < min_seconds * fps:
            continue
        hips = j[s:e][:, [J["left_hip"], J["right_hip"]]]
        knees = j[s:e][:, [J["left_knee"], J["right_knee"]]]
        thigh = (knees - hips)[..., :2].mean(axis=(0, 1))
        if np.linalg.norm(thigh) < 1e-6:
            continue
        fwd = thigh / np.linalg.norm(thigh)
        yaw = float(np.arctan2(fwd[1], fwd[0]))
        hip_mid = np.median(hips.mean(axis=1), axis=0)
        height = float(np.percentile(hips.mean(axis=1)[:, 2], SEAT_HIP_PERCENTILE) - SEAT_BELOW_HIP_M)
        if height < MIN_SEAT_M:
            continue
        thigh_len = float(np.median(np.linalg.norm(knees - hips, axis=-1)))
        width = float(np.median(np.linalg.norm(hips[:, 0] - hips[:, 1], axis=-1))) + 2 * SEAT_SIDE_M
        front = _front_clear(limbs, hip_mid, fwd, SEAT_THIGH_SHARE * thigh_len, width, height)
        back = SEAT_BEHIND_HIP_M
        centre = hip_mid[:2] + fwd * (front - back) / 2
        meta = {"seat_height": height, "seat_center": [0.0, 0.0, height], "sit_yaw": 0.0,
                "frames": [int(s), int(e)], "fitted": "seated pelvis"}
        out.append(box_object(f"seat_{len(out)}", "seat", float(centre[0]), float(centre[1]), yaw,
                              front + back, width, height, meta, legs=True, avoid=j))
    return out


def fit_beds(joints: np.ndarray, states: np.ndarray, fps: float = 30.0, min_seconds: float = 1.0) -> list[SceneObject]:
    """One bed box per lying run (>= ``min_seconds``) whose pelvis rests above ``BED_MIN_HEIGHT_M``;
    the box spans the body's extent along its length (+0.2 m) and is 0.9 m wide."""
    j = np.asarray(joints, np.float64)
    out = []
    body = [J[n] for n in ("pelvis", "spine1", "spine2", "spine3", "neck", "head", "left_hip", "right_hip")]
    for s, e in segments(np.asarray(states) == MOTION_STATES.index("lie")):
        if e - s < min_seconds * fps:
            continue
        seg = j[s:e]
        if np.median(seg[:, J["pelvis"], 2]) < BED_MIN_HEIGHT_M:
            continue  # on the floor
        axis = (seg[:, J["head"], :2] - seg[:, J["pelvis"], :2]).mean(0)
        axis = axis / max(np.linalg.norm(axis), 1e-9)
        yaw = float(np.arctan2(axis[1], axis[0]))
        pts = seg.reshape(-1, 3)[:, :2]
        along = pts @ axis
        across = pts @ np.array([-axis[1], axis[0]])
        length = float(np.ptp(along)) + 0.2
        centre = axis * (along.min() + along.max()) / 2 + np.array([-axis[1], axis[0]]) * (across.min() + across.max()) / 2
        height = float(np.percentile(seg[:, body, 2].min(axis=1), 5) - BED_BELOW_BODY_M)
        meta = {"lie_center": [0.0, 0.0, height], "lie_yaw": 0.0, "lie_length": length,
                "frames": [int(s), int(e)], "fitted": "lying body"}
        out.append(box_object(f"bed_{len(out)}", "bed", float(centre[0]), float(centre[1]), yaw, length, 0.9,
                              height, meta))
    return out


def fit_tables(joints: np.ndarray, states: np.ndarray, fps: float = 30.0) -> list[SceneObject]:
    """One table (a top on four legs) per run of >= ``TABLE_MIN_S`` s in which a hand rests: the
    wrist still (< ``HAND_STILL_MPS``), ``TABLE_REACH_M`` or more in front of the pelvis, with a
    top ``WRIST_ABOVE_TOP_M`` under it between ``TABLE_HEIGHT_M`` and ``TABLE_KNEE_CLEAR_M`` above
    the knees (legs fit under it; a hand on the lap or the hip is no table). The table faces the
    body, the hand ``TABLE_EDGE_M`` inside its near edge; one that any joint enters during the run
    is dropped. joints (T, 24, 3) m; states per frame (``MOTION_STATES``)."""
    from scipy.ndimage import uniform_filter1d

    from .motion_labels import body_features

    j = np.asarray(joints, np.float64)
    if len(j) < TABLE_MIN_S * fps:
        return []
    heading = body_features(j, fps)["heading"]
    fwd = np.stack([np.cos(heading), np.sin(heading)], axis=-1)  # (T, 2)
    out: list[SceneObject] = []
    for side in ("left", "right"):
        w = j[:, J[f"{side}_wrist"]]
        speed = uniform_filter1d(np.linalg.norm(np.gradient(w, axis=0), axis=-1) * fps, max(1, int(fps / 4)),
                                 mode="nearest")
        top = w[:, 2] - WRIST_ABOVE_TOP_M
        ahead = ((w[:, :2] - j[:, J["pelvis"], :2]) * fwd).sum(-1)
        knees = j[:, [J["left_knee"], J["right_knee"]], 2].max(axis=1)
        ok = (speed < HAND_STILL_MPS) & (ahead > TABLE_REACH_M) & (top > TABLE_HEIGHT_M[0]) & \
             (top < TABLE_HEIGHT_M[1]) & (top > knees + TABLE_KNEE_CLEAR_M)
        for s, e in segments(ok):
            if e - s < TABLE_MIN_S * fps:
                continue
            f = fwd[s:e].mean(0)
            f = f / max(np.linalg.norm(f), 1e-9)
            hand = np.median(w[s:e, :2], axis=0)
            height = float(np.median(top[s:e]))
            depth, width = TABLE_SIZE_M
            centre = hand + f * (depth / 2 - TABLE_EDGE_M)
            meta = {"surface_height": height, "surface_size": [depth, width], "frames": [int(s), int(e)],
                    "fitted": f"resting {side} hand"}
            t = box_object(f"table_{len(out)}", "table", float(centre[0]), float(centre[1]),
                           float(np.arctan2(f[1], f[0])), depth, width, height, meta, legs=True, avoid=j)
            if not t.world_mesh().contains(j[s:e].reshape(-1, 3)).any():
                out.append(t)
    return out


def _merge_same(objs: list[SceneObject]) -> list[SceneObject]:
    """One object per place: fits within ``SAME_PLACE_M`` (centre) and ``SAME_PLACE_M`` (height) of
    each other are the same seat / bed used again; the lowest of them is kept (a body that sank
    deeper in one run is not inside it) and every run is listed in its meta "runs"."""
    kept: list[SceneObject] = []
    for o in objs:
        o.meta["runs"] = [o.meta["frames"]]
        k = next((i for i, q in enumerate(kept) if np.linalg.norm(q.pose[:3, 3] - o.pose[:3, 3]) < SAME_PLACE_M
                  and abs(q.meta["size"][2] - o.meta["size"][2]) < SAME_PLACE_M), None)
        if k is None:
            kept.append(o)
            continue
        runs = kept[k].meta["runs"] + o.meta["runs"]
        if o.meta["size"][2] < kept[k].meta["size"][2]:
            o.name, kept[k] = kept[k].name, o
        kept[k].meta["runs"] = sorted(runs)
    return kept


def in_the_way(obj: SceneObject, joints: np.ndarray, states: np.ndarray, fps: float = 30.0) -> bool:
    """Is a fitted object where the body is at other times? True when some joint of joints
    (T, 24, 3) m is inside its mesh on at least ``IN_THE_WAY_S`` s of frames farther than
    ``TRANSITION_S`` s from every run of its state ("sit" for a seat, "lie" for a bed; per-frame
    ``states``): a kneel or a sit on the floor taken for a seat, a body on the floor taken for one
    on a bed; or when a torso joint (pelvis, hips, spine) is inside its bounding box on
    ``TORSO_INSIDE_S`` s of any frames but its own runs (meta "runs"; sitting down and getting up
    never put the torso inside a seat: the body is on the floor where it stands)."""
    j = np.asarray(joints, np.float64)
    own = np.zeros(len(j), bool)
    for s, e in obj.meta.get("runs", [obj.meta["frames"]]):
        own[s:e] = True
    torso = (j[~own][:, list(TORSO_JOINTS)] - obj.pose[:3, 3]) @ obj.pose[:3, :3]  # object frame
    lo, hi = obj.mesh.bounds  # the torso cannot be under a seat's top either: its whole box counts
    if np.all((torso > lo) & (torso < hi), axis=-1).any(axis=1).sum() >= TORSO_INSIDE_S * fps:
        return True
    pad = int(round(TRANSITION_S * fps))
    t = np.arange(len(joints))
    other = np.ones(len(t), bool)
    if obj.category in ("seat", "bed"):
        runs = segments(np.asarray(states) == MOTION_STATES.index("lie" if obj.category == "bed" else "sit"))
    else:  # a table: its own resting-hand runs
        runs = obj.meta.get("runs", [obj.meta["frames"]])
    for s, e in runs:
        other &= (t < s - pad) | (t >= e + pad)
    if not other.any():
        return False
    pts = np.asarray(joints, np.float64)[other]
    inside = obj.world_mesh().contains(pts.reshape(-1, 3)).reshape(pts.shape[:2]).any(axis=1)
    return bool(inside.sum() >= IN_THE_WAY_S * fps)


def fit_scene(joints: np.ndarray, states: np.ndarray, name: str = "fitted", fps: float = 30.0) -> Scene:
    """A scene for a real clip: the fitted seats, beds and tables (the floor z = 0 is implicit), one
    per place, without those the body goes through at other times (``in_the_way``)."""
    fits = [_merge_same(f(joints, states, fps)) for f in (fit_seats, fit_beds, fit_tables)]
    objects = [o for objs in fits for o in objs if not in_the_way(o, joints, states, fps)]
    return Scene(name=name, objects={o.name: o for o in objects}, meta={"fitted_to_motion": True})


def fitted_contacts(joints: np.ndarray, states: np.ndarray, fps: float = 30.0) -> tuple[Scene, np.ndarray, list[str]]:
    """The fitted scene, per-joint contacts (T, 24) bool by the TRUMANS rule
    (``trumans.contacts.rule.joint_contacts``, floor included) and the contact object of each
    joint-frame (T, 24) names ("" = none)."""
    from .contacts.rule import ContactScene, joint_contacts

    scene = fit_scene(joints, states, fps=fps)
    res = joint_contacts(np.asarray(joints, np.float64), ContactScene(scene))
    names = np.array(list(res.names) + [""])
    return scene, res.contact, names[res.object_index].tolist()
