"""Seated desk work: typing on a keyboard and using a mouse (conventions in ``trumans.synth.hands``).

Both take the seated body's own motion (``posture.sit``) as ``base``; the arms reach the device,
work, and return to the base pose on the last frame. Grasp flags (keyed by the wrist joint) mark
the frames a hand rests on the device.
"""
from __future__ import annotations

import numpy as np

from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.rotations import yaw_matrix
from trumans.skeleton import forward_kinematics
from ..motion import Motion, yaw_of
from ..poses import ease
from .core import (
    PALM_GAP, WRIST, OutOfReach, Side, apply_h, base_arrays, check_pose, check_side, finish_motion, hand_frame,
    hand_world, inv_h, is_seated, palm_points, reach_hold_retract, to_h, wrist_targets,
)
from .lean import choose_lean, lean_between, lean_travel
from .timing import phases

__all__ = ["TYPE_HOVER", "type_keyboard", "use_mouse"]

TYPE_HOVER = 0.015  # m, palm point above the key surface between taps (taps add up to 8 mm)


def _lean_for(base: Motion, frame: int, wrists: dict[str, np.ndarray], spread: np.ndarray) -> tuple[float, float]:
    """The lean that lets every hand reach its wrist target (3,) moved by each of ``spread`` (K, 3)."""
    rot, root, off = base_arrays(base)
    best = (0.0, 0.0)
    for side, w in wrists.items():
        p, d = choose_lean(rot[frame], root[frame], off, side, w[None] + spread, is_seated(base))
        best = (max(best[0], p), max(best[1], d))
    return best


def _lean_in(base: Motion, kind: str, rng: np.random.Generator, dist: float, pitch: float,
             drop: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """The reach / work / retract phases of desk primitive ``kind``, timed for a palm travel of
    ``dist`` m (or the lean's own travel, when longer), and the base leaned in (pitch rad, drop m)
    for the work. Returns (rot, root, joints (T, 24, 3) of the leaned body, first work frame, last)."""
    rot, root, off = base_arrays(base)
    seated = is_seated(base)
    dist = max(dist, lean_travel(rot[0], root[0], off, pitch, drop, seated))
    ph = phases(kind, base.num_frames, rng, base.fps, moves={"reach": dist, "retract": dist})
    r1, k1 = ph["reach"][1], ph["work"][1]
    rot, root = lean_between(rot, root, off, pitch, drop, seated, r1, k1)
    return rot, root, forward_kinematics(rot, root, off)[0], r1, k1


def type_keyboard(base: Motion, keyboard: SceneObject, pose: np.ndarray, rng: np.random.Generator) -> Motion:
    """Type on ``keyboard`` (world pose (4, 4)): both palm points go to ``TYPE_HOVER`` above the
    keyboard's ``press_points`` (left hand to the first, right to the second), palms down, fingers
    pointing away from the user (the keyboard's local -x); while typing each hand taps (3-5 Hz,
    up to 8 mm) and drifts slowly along the keys (+-1.5 cm). Label 'type'; grasp flags while typing."""
    pose = check_pose(pose, "pose")
    if "press_points" not in keyboard.meta:
        raise ValueError(f"object {keyboard.name!r} has no press_points meta (a keyboard or laptop is needed)")
    T = base.num_frames
    rot, root, off = base_arrays(base)
    up = pose[:3, 2]
    n = -up
    fingers = -pose[:3, 0]
    pts = {s: apply_h(pose, keyboard.meta["press_points"][k]) for k, s in enumerate(("left", "right"))}
    Rh = {s: hand_frame(n, fingers, s) for s in pts}
    palm = {s: pts[s] + TYPE_HOVER * up for s in pts}
    lat = pose[:3, 1]
    spread = np.array([0.015 * lat, -0.015 * lat, 0.008 * up + 0.015 * lat, 0.008 * up - 0.015 * lat])
    pitch, drop = _lean_for(base, 0, {s: wrist_targets(palm[s], Rh[s], off, s) for s in pts}, spread)
    pb0 = palm_points(base.joints())
    dist = max(np.linalg.norm(palm[s] - pb0[f, k]) for k, s in enumerate(("left", "right")) for f in (0, -1)) + 0.05
    rot, root, P, r1, k1 = _lean_in(base, "type", rng, dist, pitch, drop)
    t = np.arange(T)
    tsec = t / base.fps
    typing = (t >= r1) & (t <= k1)
    env = np.clip(np.minimum(t - r1, k1 - t) / (0.3 * base.fps), 0, 1) * typing
    lateral = pose[:3, 1]
    for k, side in enumerate(("left", "right")):
        pb = palm_points(P)[:, k]
        f, ph0 = rng.uniform(3.0, 5.0), rng.uniform(0, 2 * np.pi)
        tap = 0.008 * (0.5 + 0.5 * np.sin(2 * np.pi * f * tsec + ph0)) ** 2
        drift = 0.015 * np.sin(2 * np.pi * rng.uniform(0.1, 0.25) * tsec + rng.uniform(0, 2 * np.pi))
        work = palm[side] + (env * tap)[:, None] * up + (env * drift)[:, None] * lateral
        rot, _ = reach_hold_retract(rot, root, off, side, pb, work, np.broadcast_to(Rh[side], (T, 3, 3)), r1, k1,
                                    (palm[side], up), (palm[side], up), 2.5, f"type ({side} hand)")
    grasp = {WRIST[s]: typing.copy() for s in ("left", "right")}
    return finish_motion(base, rot, root, [ActionInterval("type", 0, T)],
                         {keyboard.name: np.broadcast_to(pose, (T, 4, 4)).copy()}, grasp)


def use_mouse(base: Motion, mouse: SceneObject, pose: np.ndarray, rng: np.random.Generator,
              side: Side | None = None) -> Motion:
    """Use ``mouse`` (world pose (4, 4)): the hand (default: the side of the body the mouse is on)
    reaches its ``grip_point`` (palm point ``PALM_GAP`` above it, palm down, fingers along the
    mouse's local -x), then moves it on the desk (smooth random path within +-3.5 cm — less when the
    hand cannot reach that far: at least +-1.5 cm, else OutOfReach — yaw +-8 deg,
    in the mouse's own horizontal plane: it stays on the surface), lets go and returns. The mouse
    follows the hand rigidly while gripped and stays where it was left. Label 'use_mouse'."""
    pose = check_pose(pose, "pose")
    gp = mouse.meta.get("grip_point", mouse.meta.get("grasp_point"))
    if gp is None:
        raise ValueError(f"object {mouse.name!r} has no grip_point / grasp_point meta")
    T = base.num_frames
    rot, root, off = base_arrays(base)
    if side is None:
        yaw = yaw_of(rot[0, 0])
        rel = yaw_matrix(-yaw) @ (pose[:3, 3] - root[0])
        side = "left" if rel[1] > 0 else "right"
    check_side(side)
    up = pose[:3, 2]
    grip = apply_h(pose, gp)
    Rh = hand_frame(-up, -pose[:3, 0], side)
    palm = grip + PALM_GAP * up
    ex, ey = pose[:3, 0], pose[:3, 1]
    corners = np.array([ex + ey, ex - ey, -ex + ey, -ex - ey])
    wrist = {side: wrist_targets(palm, Rh, off, side)}
    for amp in (0.035, 0.025, 0.015):  # the largest mouse range the hand reaches (+1 cm for the turn)
        try:
            pitch, drop = _lean_for(base, 0, wrist, (amp + 0.01) * corners)
            break
        except OutOfReach:
            if amp == 0.015:
                raise
    pb0 = palm_points(base.joints())[:, 0 if side == "left" else 1]
    dist = max(np.linalg.norm(palm - pb0[0]), np.linalg.norm(palm - pb0[-1])) + 0.09
    rot, root, P, r1, k1 = _lean_in(base, "use_mouse", rng, dist, pitch, drop)
    t = np.arange(T)
    tsec = t / base.fps
    working = (t >= r1) & (t <= k1)
    # Mouse motion in its own frame: zero at the grip frame, smooth, bounded.
    env = ease(np.clip((t - r1) / (0.4 * base.fps), 0, 1)) * (t >= r1)
    env_end = np.where(t > k1, env[np.minimum(k1, T - 1)], env)
    sig = []
    tt = np.minimum(tsec, k1 / base.fps)
    for _ in range(3):  # two sines per channel (x, y, yaw), zero at the grip frame
        f = rng.uniform(0.15, 0.6, 2)
        a = rng.uniform(0.4, 0.6, 2)
        ph0 = rng.uniform(0, 2 * np.pi, 2)
        wave = lambda x: (a[:, None] * np.sin(2 * np.pi * f[:, None] * x + ph0[:, None])).sum(0)  # noqa: E731
        sig.append((wave(tt) - wave(np.array([r1 / base.fps]))) / 2.0)
    dx = np.clip(amp * np.asarray(sig[0]) * env_end, -amp, amp)
    dy = np.clip(amp * np.asarray(sig[1]) * env_end, -amp, amp)
    dyaw = np.clip(np.radians(8.0) * np.asarray(sig[2]) * env_end, -np.radians(8), np.radians(8))
    M = to_h(yaw_matrix(dyaw), np.stack([dx, dy, np.zeros(T)], -1))
    track = pose @ M  # (T, 4, 4) mouse poses (local-frame motion keeps it on its plane)
    inv0 = inv_h(pose)
    palm_l, R_l = apply_h(inv0, palm), pose[:3, :3].T @ Rh
    palm_t = apply_h(track, palm_l)
    R_t = track[:, :3, :3] @ R_l
    pb = palm_points(P)[:, 0 if side == "left" else 1]
    R = np.where((t <= k1)[:, None, None], R_t, np.broadcast_to(R_t[k1], (T, 3, 3)))
    rot, _ = reach_hold_retract(rot, root, off, side, pb, palm_t, R, r1, k1, (palm, up), (palm_t[k1], up), 2.5,
                                f"use_mouse {mouse.name}")
    H = hand_world(rot, root, off, side)
    offset = inv_h(H[r1]) @ pose
    out = np.broadcast_to(pose, (T, 4, 4)).copy()
    out[working] = H[working] @ offset
    out[t > k1] = out[k1]
    return finish_motion(base, rot, root, [ActionInterval("use_mouse", 0, T)], {mouse.name: out},
                         {WRIST[side]: working})
