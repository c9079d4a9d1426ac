"""Raising a held object to the face: drinking from a bottle or cup, a phone call (conventions in
``hands.core``). Both start and end at the carry pose of ``hands.objects.pick_up``."""
from __future__ import annotations

import numpy as np

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import rodrigues, unit, yaw_matrix
from trumans.skeleton import JOINT_INDEX, forward_kinematics
from ..motion import Motion, yaw_of
from ..poses import ease, slerp_rot
from .core import (
    ELBOW_DIR, SIGN, WRIST, actor_scale, base_arrays, finish_motion, hand_world, heading_frame, inv_h, place_arm,
    require_reached, to_h, wrist_to_palm,
)
from .objects import Hold, carry_pose, object_height
from .timing import phases, ramp

__all__ = ["drink", "phone_call"]

def _to_face(base: Motion, hold: Hold, kind: str, rng: np.random.Generator, obj_target) -> Motion:
    """Shared timing of drink / phone_call: raise the object to ``obj_target(rot, root, s)`` ->
    (T, 4, 4) object poses, keep it there, lower back to the carry pose."""
    side = hold.side
    T = base.num_frames
    rot, root, off = base_arrays(base)
    c_p, c_R = carry_pose(base, hold)
    H0 = obj_target(rot[:1], root[:1], off, np.zeros(1))[0] @ inv_h(hold.offset)
    dist = np.linalg.norm(wrist_to_palm(H0[:3, 3], H0[:3, :3], off, side) - c_p[0]) + 0.15
    ph = phases(kind, T, rng, base.fps, moves={"raise": dist, "lower": dist})
    a0, a1 = ph["raise"]
    b0, b1 = ph[list(ph)[1]]
    t = np.arange(T)
    w = ramp(T, a0, a1) * (1 - ramp(T, b1, T - 1))
    To = obj_target(rot, root, off, np.clip((t - b0) / max(b1 - b0, 1), 0, 1))
    Ht = To @ inv_h(hold.offset)
    palm_t = wrist_to_palm(Ht[:, :3, 3], Ht[:, :3, :3], off, side)
    # The arm is at the carry pose at both ends; the face pose is blended in with w.
    F = heading_frame(base)
    bow = F[:, :3, :3] @ (actor_scale(off) * np.array([0.15, 0.05 * SIGN[side], 0.0]))
    path = c_p + w[:, None] * (palm_t - c_p) + (4.0 * w * (1 - w))[:, None] * bow  # keep clear of the shoulder
    R = slerp_rot(c_R, Ht[:, :3, :3], w)
    elbow = (1 - w)[:, None] * ELBOW_DIR[side] + w[:, None] * np.array([0.2, 0.9 * SIGN[side], -1.0])
    rot, reached = place_arm(rot, root, off, side, path, R, np.ones(T), elbow_dir=elbow)
    require_reached(reached, t == a1, f"{kind} {hold.name}")  # the object arrives at the face
    H = hand_world(rot, root, off, side)
    return finish_motion(base, rot, root, [ActionInterval(kind, 0, T)], {hold.name: H @ hold.offset},
                   {WRIST[side]: np.ones(T, dtype=bool)})


def _face_frame(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Head positions (T, 3) and heading rotations (T, 3, 3)."""
    P, _ = forward_kinematics(rot, root, offsets)
    yaw = yaw_of(rot[:, 0])
    return P[:, JOINT_INDEX["head"]], yaw_matrix(yaw)


def drink(base: Motion, hold: Hold, obj: SceneObject, rng: np.random.Generator) -> Motion:
    """Drink from a held bottle / cup: raise its top to the mouth, tilt it back (60 -> 95 deg over
    the sip), lower it to the carry pose. Starts and ends at the carry pose; label 'drink'."""
    top = np.array([0.0, 0.0, object_height(obj)])
    tilt0, tilt1 = np.radians(rng.uniform(50, 65)), np.radians(rng.uniform(85, 105))
    sc = actor_scale(base.offsets)
    R_carry_obj = hold.carry_rot @ hold.offset[:3, :3]  # object rotation in the heading frame

    def target(rot, root, off, s):
        head, Ry = _face_frame(rot, root, off)
        mouth = head + (Ry @ (sc * np.array([0.10, 0.0, -0.05])))
        tilt = tilt0 + (tilt1 - tilt0) * ease(s)
        left = Ry[:, :, 1]
        Ro = rodrigues(left, -tilt) @ Ry @ R_carry_obj  # top of the object tips back towards the mouth
        return to_h(Ro, mouth - (Ro @ top))

    return _to_face(base, hold, "drink", rng, target)


def phone_call(base: Motion, hold: Hold, obj: SceneObject, rng: np.random.Generator) -> Motion:
    """Hold a phone to the ear on the holding hand's side: its face (local z) turned away from the
    head, its long axis from the ear towards the mouth; back to the carry pose. Label 'phone_call'."""
    sc = actor_scale(base.offsets)
    c = obj.mesh.bounds.mean(axis=0)
    sz = obj.meta.get("size", obj.mesh.extents.tolist())
    long_axis = 1 if sz[1] >= sz[0] else 0
    sgn = SIGN[hold.side]
    pitch = np.radians(rng.uniform(35, 55))

    def target(rot, root, off, s):
        head, Ry = _face_frame(rot, root, off)
        ear = head + Ry @ (sc * np.array([0.0, sgn * 0.10, 0.02]))
        out = Ry @ np.array([0.0, sgn, 0.0])  # local +z (the palm side) points away from the head
        along = Ry @ np.array([np.sin(pitch), 0.0, -np.cos(pitch)])  # ear -> mouth-ish, forward-down
        z = out
        a = unit(along - (along * z).sum(-1, keepdims=True) * z)
        if long_axis == 1:  # local y = a, local x = y x z
            Ro = np.stack([np.cross(a, z), a, z], axis=-1)
        else:
            Ro = np.stack([a, np.cross(z, a), z], axis=-1)
        p = ear + 0.5 * sz[2] * out - (Ro @ c)
        return to_h(Ro, p)

    return _to_face(base, hold, "phone_call", rng, target)
