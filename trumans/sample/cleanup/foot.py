"""Foot cleanup of sampled episodes: planted feet locked in place on the floor, legs re-solved.

The generator's feet slide and sink (foot skate, floor error). After each episode, over the
context frames (fixed, already cleaned) followed by the new frames:

1. contacts per foot from the height of its lowest foot joint (ankle / toe) above its resting
   height and from its horizontal speed, with hysteresis (enter when low *and* slow, leave when
   high *or* fast; in between the previous state holds); on upright frames where neither foot is
   planted (the network's feet both slide, which would give each its own swing: a flight phase,
   which walking does not have), the foot that is lower and slower is planted (``support_foot``);
2. over each contact run the foot is locked on the floor at its mean position over the run (at the
   last context frame when the run began before the episode, so locks carry across seams); a run
   whose lock leaves the leg's reach (hip to lock farther than thigh + shin + ``reach_slack``) ends
   at that frame (the person lifts that foot; the clamped IK would drag it off the lock and up) and
   the shortened runs are re-locked (``reach_passes``); outside contacts
   a foot under the floor is lifted onto it; the correction fades out over ``blend`` frames after
   a run and in over ``blend`` frames before it (new frames only);
3. a swing (the frames between two locks, or between the last context frame and a lock) goes from
   where the foot left the floor to where it lands on a smooth path: horizontally a cubic Hermite
   curve from the first anchor (with its velocity when that anchor is a mid-swing context frame,
   else at rest) to the landing lock at rest, so it leaves and lands without a jump or a slide (no
   popping at a lock's release); vertically the network's height, moved by the anchors' height
   corrections (smoothstep), and raised to at least a clearance arc ``h sin(pi u)`` over the swing
   (u in [0, 1]) with ``h = min(swing_height, swing_ratio x step length)``: the generator's swing foot
   shuffles 0-4 cm over the floor at 2-7 m/s, which is a foot sliding on the floor, not a step.
   A swing still in the air at the episode's end keeps the network's path and rises over
   ``tail_rise`` frames to the clearance of a step twice its way so far; the next episode starts
   it from that (context) frame with its velocity and height and lands it;
4. with the scene's signed distance field (``clean_feet(..., sdf=)``, given by the sampler), a foot
   target whose ankle or toe is inside furniture (closer than its core radius) moves out along the
   field's gradient, horizontally while planted (the lock moves as one), in 3D while swinging;
5. the leg is re-solved with an analytic two-bone IK on joint positions (law of cosines): the hip
   stays, the ankle goes to its target (clamped to the leg's reach), the knee stays in the plane
   of its current bend, the toe keeps its offset from the ankle, so every bone length is exact;
   with the field, a knee that ends inside furniture (a foot lifted onto the floor bends the knee
   forward, into a wall or a table) turns outward about the hip-ankle axis (``knee_out_of_scene``).

The generator outputs joint positions, not rotations, so the positional form of the two-bone
solve (``trumans.ik.limb`` solves the same chain on rotations) is used; no rotation fit per episode.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.contacts.rule import JOINT_CORE_RADIUS
from trumans.ik.limb import two_bone_positions
from trumans.skeleton import FOOT_REST_HEIGHT, LEG_CHAINS
from trumans.stance import planted

from trumans.easing import smoothstep
from trumans.sample.cleanup.common import episode_joints

__all__ = ["FootCleanupConfig", "foot_contacts", "support_foot", "out_of_scene", "knee_out_of_scene",
           "clean_feet"]

ANKLE_REST, TOE_REST = FOOT_REST_HEIGHT[0], FOOT_REST_HEIGHT[2]  # m above the floor (trumans.skeleton)


@dataclass(frozen=True)
class FootCleanupConfig:
    """enter_height / exit_height: foot height above rest (m) to start / end a contact;
    enter_speed / exit_speed: horizontal foot speed (m/s) to start / end a contact;
    blend: frames over which a lock's correction fades in and out (free frames not between two
    anchors); swing_height (m) / swing_ratio: the least clearance of a swing's lowest foot joint at
    mid-swing, ``min(swing_height, swing_ratio x step length)`` (0 = the network's height);
    tail_rise: frames over which a swing still in the air at the episode's end rises to its clearance;
    support: plant one foot on upright frames where neither is (``support_foot``; walking has no
    flight phase), the one whose height + ``support_speed_weight`` x horizontal speed (m per m/s) is
    lower; lock_at_mean: a contact run begun in this episode is locked at its mean position, not at
    its first (a sliding foot is moved half as far, so a locked leg overstretches less);
    reach_passes: times a contact run is ended at its first frame whose lock is out of the leg's
    reach and the shortened runs re-locked (0 = off; a run re-locked at its new mean can leave
    reach earlier, hence more than one pass); reach_slack: m beyond the reach that a lock may be and
    still hold (the IK's clamp lifts the foot off it by about as much; releasing every lock a few mm
    out would leave both feet in the air more often); enabled: run the foot cleanup; scene: with
    the scene's field, move foot targets and knees out of furniture (steps 4, 5); support_margin /
    support_upright: ``support_foot``'s ``margin`` / ``upright``; scene_iters / scene_max_step:
    ``out_of_scene``'s ``iters`` / ``max_step``; knee_max_angle / knee_steps: ``knee_out_of_scene``'s
    ``max_angle`` / ``steps``; replant_distance: m that the network may move a foot away from its lock
    on a seated frame (``clean_feet(..., seated=)``: the feet carry little weight) before the foot is
    lifted and set down where the network puts it, ``replant_frames`` frames later (0 = off: a seated
    body kept the stagger of its last walking step, 15-19 cm where people sit with 2-5 cm); the
    re-planted foot's lowest joint rises ``replant_lift`` x sin(pi u) over the lifted frames (u in (0, 1)):
    a step, not a slide along the floor."""

    enabled: bool = True
    scene: bool = True
    enter_height: float = 0.06
    exit_height: float = 0.10
    enter_speed: float = 0.35
    exit_speed: float = 0.8
    blend: int = 3
    swing_height: float = 0.07
    swing_ratio: float = 0.2
    tail_rise: int = 3
    support: bool = True
    support_speed_weight: float = 0.1
    lock_at_mean: bool = True
    reach_passes: int = 2
    reach_slack: float = 0.02
    support_margin: float = 0.02
    support_upright: float = 0.8
    scene_iters: int = 2
    scene_max_step: float = 0.15
    knee_max_angle: float = float(np.pi / 3)
    knee_steps: int = 12
    replant_distance: float = 0.05
    replant_frames: int = 3
    replant_lift: float = 0.08

    def __post_init__(self) -> None:
        if not (self.support_margin >= 0 and self.support_upright >= 0 and self.scene_max_step > 0
                and self.scene_iters >= 1 and self.knee_steps >= 1 and 0 <= self.knee_max_angle <= np.pi):
            raise ValueError(f"need support_margin, support_upright >= 0, scene_max_step > 0, scene_iters, knee_steps "
                             f">= 1 and knee_max_angle in [0, pi], got {self.support_margin}, {self.support_upright}, "
                             f"{self.scene_max_step}, {self.scene_iters}, {self.knee_steps}, {self.knee_max_angle}")
        if not 0 <= self.enter_height <= self.exit_height:
            raise ValueError(f"need 0 <= enter_height <= exit_height, got {self.enter_height}, {self.exit_height}")
        if not 0 <= self.enter_speed <= self.exit_speed:
            raise ValueError(f"need 0 <= enter_speed <= exit_speed, got {self.enter_speed}, {self.exit_speed}")
        if self.reach_passes < 0 or not self.reach_slack >= 0:
            raise ValueError(f"need reach_passes >= 0 and reach_slack >= 0 m, got {self.reach_passes}, {self.reach_slack}")
        if self.blend < 0:
            raise ValueError(f"blend must be >= 0 frames, got {self.blend}")
        if not (self.replant_distance >= 0 and self.replant_lift >= 0) or self.replant_frames < 1:
            raise ValueError(f"need replant_distance, replant_lift >= 0 m and replant_frames >= 1, got "
                             f"{self.replant_distance}, {self.replant_lift}, {self.replant_frames}")
        if not (self.swing_height >= 0 and self.swing_ratio >= 0 and self.tail_rise >= 1):
            raise ValueError(f"need swing_height, swing_ratio >= 0 and tail_rise >= 1, got {self.swing_height}, "
                             f"{self.swing_ratio}, {self.tail_rise}")


def _foot_height(joints: np.ndarray, ankle: int, toe: int) -> np.ndarray:
    """(..., T) height of the lower of ankle / toe above its resting height, m."""
    return np.minimum(joints[..., ankle, 2] - ANKLE_REST, joints[..., toe, 2] - TOE_REST)


def foot_contacts(joints: np.ndarray, fps: float, config: FootCleanupConfig = FootCleanupConfig(),
                  initial: np.ndarray | bool = False) -> np.ndarray:
    """joints (B, T, 24, 3) world m -> (B, T, 2) bool contacts of the (left, right) foot
    (``trumans.stance.planted`` on the lower of ankle / toe above rest and the horizontal speed of
    their midpoint). ``initial`` (B, 2) or bool: the state before frame 0 (for frames neither
    entering nor leaving)."""
    B, T = joints.shape[:2]
    height = np.zeros((B, T, 2))
    speed = np.zeros((B, T, 2))
    for s, (_, _, ankle, toe) in enumerate(LEG_CHAINS):
        height[..., s] = _foot_height(joints, ankle, toe)
        mid = 0.5 * (joints[..., ankle, :2] + joints[..., toe, :2])
        speed[:, 1:, s] = np.linalg.norm(np.diff(mid, axis=1), axis=-1) * fps
        if T > 1:
            speed[:, 0, s] = speed[:, 1, s]
    return planted(speed, height, enter_speed=config.enter_speed, exit_speed=config.exit_speed,
                   enter_height=config.enter_height, exit_height=config.exit_height, initial=initial)


def _upright(joints: np.ndarray, leg_length: float, upright: float) -> np.ndarray:
    """(B, T) bool: the hips' midpoint is at least ``upright`` x ``leg_length`` (m) above the lower ankle."""
    (lhip, _, lankle, _), (rhip, _, rankle, _) = LEG_CHAINS
    hip_z = 0.5 * (joints[..., lhip, 2] + joints[..., rhip, 2])
    return hip_z - np.minimum(joints[..., lankle, 2], joints[..., rankle, 2]) >= upright * leg_length


def support_foot(contact: np.ndarray, joints: np.ndarray, leg_length: float, fps: float, fixed: int = 0,
                 margin: float = 0.02, upright: float = 0.8, speed_weight: float = 0.0) -> np.ndarray:
    """(B, T, 2) contacts -> the same with one foot planted on every new frame (>= ``fixed``) where
    neither is and the body stands upright (hip above the lower ankle by at least ``upright`` x
    ``leg_length``, m): the lower foot (lowest foot joint above rest), switching only when the other
    is ``margin`` m lower or planted (hysteresis). Walking has no flight phase; a generated body whose
    feet both slide too fast to count as planted stands on the one nearer the floor. Sitting down,
    crouching and lying are left to the detected contacts."""
    B, T, _ = contact.shape
    legs = list(LEG_CHAINS)
    h = np.stack([_foot_height(joints, a, t) for _, _, a, t in legs], -1)  # (B, T, 2)
    stands = _upright(joints, leg_length, upright)
    score = h.copy()
    if speed_weight > 0 and T > 1:
        mid = np.stack([0.5 * (joints[..., a, :2] + joints[..., t, :2]) for _, _, a, t in legs], 2)  # (B, T, 2, 2)
        v = np.zeros((B, T, 2))
        v[:, 1:] = np.linalg.norm(np.diff(mid, axis=1), axis=-1) * fps
        v[:, 0] = v[:, 1]
        score = score + speed_weight * v  # m of height per m/s
    lower = (score[..., 1] < score[..., 0]).astype(np.int64)  # 0 left, 1 right
    one = contact.sum(-1) == 1
    pick = np.where(one, contact[..., 1].astype(np.int64), lower)
    decisive = one | (np.abs(score[..., 0] - score[..., 1]) > margin)
    t = np.arange(T)[None]
    last = np.maximum.accumulate(np.where(decisive, t, -1), axis=1)
    foot = np.where(last >= 0, np.take_along_axis(pick, np.maximum(last, 0), axis=1), lower[:, :1])
    add = stands & ~contact.any(-1) & (t >= fixed)
    out = contact.copy()
    out[..., 0] |= add & (foot == 0)
    out[..., 1] |= add & (foot == 1)
    return out


def _fade(contact: np.ndarray, fixed: int, blend: int) -> tuple[np.ndarray, np.ndarray]:
    """For (B, T) contacts: (index (B, T) of the contact frame whose correction applies, weight (B, T)).
    Inside a run weight 1 and index t; within ``blend`` frames after / before a run the nearest run
    frame with a linearly falling weight (frames < ``fixed`` are never corrected)."""
    B, T = contact.shape
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    prev = np.maximum.accumulate(np.where(contact, t, -10 ** 6), axis=1)
    nxt = np.flip(np.minimum.accumulate(np.flip(np.where(contact, t, 10 ** 6), 1), axis=1), 1)
    dp, dn = t - prev, nxt - t
    w_p = np.clip(1 - dp / (blend + 1), 0, 1)
    w_n = np.clip(1 - dn / (blend + 1), 0, 1)
    use_prev = w_p >= w_n
    idx = np.clip(np.where(use_prev, prev, nxt), 0, T - 1)
    w = np.where(use_prev, w_p, w_n)
    w[:, :fixed] = 0.0
    return idx, w


def _swing_paths(ankle: np.ndarray, target: np.ndarray, height: np.ndarray, contact: np.ndarray, fixed: int,
                 config: FootCleanupConfig) -> np.ndarray:
    """ankle / target (B, T, 3): the network's ankle and its corrected target (locks, floor);
    height (B, T): lowest foot joint above rest; contact (B, T) -> target with every swing between
    two anchors on its smooth path (module doc, step 3). Anchors: contact frames >= ``fixed - 1``
    and the last context frame; frames < ``fixed`` are kept."""
    B, T = contact.shape
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    anchor = contact.copy()
    if fixed > 0:
        anchor[:, fixed - 1] = True
    a0 = np.maximum.accumulate(np.where(anchor, t, -1), axis=1)  # last anchor at or before t
    a1 = np.flip(np.minimum.accumulate(np.flip(np.where(contact, t, T), 1), axis=1), 1)  # next contact at or after t
    free = ~contact & (a0 >= 0) & (t >= fixed)
    swing, tail = free & (a1 < T), free & (a1 == T)  # tail: a swing still in the air at the window's end
    if not free.any():
        return target
    a0c, a1c = np.clip(a0, 0, T - 1), np.clip(a1, 0, T - 1)
    n = np.maximum(a1c - a0c, 1)
    u = ((t - a0c) / n)[..., None]  # (B, T, 1) in (0, 1) inside a swing
    take = lambda x, i: np.take_along_axis(x, i[..., None], axis=1)  # noqa: E731
    p0, p1 = take(target, a0c), take(target, a1c)
    # the start anchor's velocity (m per swing) and clearance when it is a mid-swing context frame, else at rest
    vel = np.zeros_like(ankle)
    vel[:, 1:] = ankle[:, 1:] - ankle[:, :-1]
    moving = ~np.take_along_axis(contact, a0c, axis=1)
    m0 = take(vel, a0c) * (n * moving)[..., None]
    low_t = height + target[..., 2] - ankle[..., 2]  # lowest foot joint above rest on the corrected target
    low0 = np.maximum(np.take_along_axis(low_t, a0c, axis=1), 0.0) * moving
    h00, h10, h01 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u, 3 * u ** 2 - 2 * u ** 3
    xy = h00 * p0[..., :2] + h10 * m0[..., :2] + h01 * p1[..., :2]  # cubic Hermite, landing at rest
    w = smoothstep(u[..., 0])
    dz0, dz1 = (p0 - take(ankle, a0c))[..., 2], (p1 - take(ankle, a1c))[..., 2]
    z = ankle[..., 2] + (1 - w) * dz0 + w * dz1  # the network's height with the anchors' corrections
    step = np.linalg.norm(p1[..., :2] - p0[..., :2], axis=-1)
    arc = np.minimum(config.swing_height, config.swing_ratio * step) * np.sin(np.pi * u[..., 0]) + (1 - w) * low0
    z = z + np.maximum(arc - (height + z - ankle[..., 2]), 0.0)
    # a tail rises over ``tail_rise`` frames to the clearance of a step twice as long as the way so
    # far (it is about half-way at the window's end) and holds it; the next episode lands it
    so_far = np.linalg.norm(ankle[:, -1:, :2] - p0[..., :2], axis=-1)
    rise = np.sin(0.5 * np.pi * np.clip((t - a0c) / max(config.tail_rise, 1), 0.0, 1.0))
    lift = np.maximum(np.minimum(config.swing_height, 2 * config.swing_ratio * so_far) * rise, low0)
    z_tail = target[..., 2] + np.maximum(lift - low_t, 0.0)
    out = target.copy()
    out[..., :2] = np.where(swing[..., None], xy, target[..., :2])
    out[..., 2] = np.where(swing, z, np.where(tail, z_tail, target[..., 2]))
    return out


def out_of_scene(ankle: np.ndarray, toe_off: np.ndarray, sdf, radii: tuple[float, float], free: np.ndarray | None = None,
                 iters: int = 2, max_step: float = 0.15) -> np.ndarray:
    """Foot targets (B, T, 3) moved out of the scene: where the ankle or the toe (ankle + ``toe_off``)
    is closer to a surface than its ``radii`` (m), the ankle moves along the field's gradient by the
    depth (at most ``max_step`` m per iteration): horizontally on planted frames (the foot stays on
    the floor; a lock's frames share one target, so they move together and the lock holds), in 3D
    on ``free`` (B, T) frames (a swing under a seat's top goes over it). sdf: ``SceneSDF`` (floor
    excluded)."""
    import torch

    out = np.array(ankle, dtype=np.float64, copy=True)
    r = np.asarray(radii, dtype=np.float64)
    for _ in range(iters):
        pts = np.stack([out, out + toe_off], -2)  # (B, T, 2, 3)
        d, g = sdf.value_and_gradient(torch.as_tensor(pts, dtype=torch.float32))
        depth = r - d.double().numpy()  # (B, T, 2)
        g = g.double().numpy()
        if free is None:
            g[..., 2] = 0.0
        else:
            g[..., 2] *= free[..., None]
        n = np.linalg.norm(g, axis=-1, keepdims=True)
        move = np.where((depth > 0)[..., None] & (n > 1e-6), g / np.maximum(n, 1e-6) * np.minimum(depth, max_step)[..., None], 0.0)
        pick = np.argmax(np.where(depth > 0, depth, -np.inf), axis=-1)  # the deeper of ankle / toe
        step = np.take_along_axis(move, pick[..., None, None], axis=-2)[..., 0, :]
        if not np.abs(step).any():
            break
        out += step
    return out


def _run_start(c: np.ndarray, fixed: int) -> np.ndarray:
    """(B, T) contacts -> (B, T) first frame of the run each contact frame belongs to (the last
    context frame ``fixed - 1`` for runs begun before it); meaningless on free frames."""
    B, T = c.shape
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    begins = c & ~np.concatenate([np.zeros((B, 1), bool), c[:, :-1]], 1)
    start = np.maximum.accumulate(np.where(begins, t, 0), axis=1)
    return np.maximum(start, min(fixed, T) - 1) if fixed > 0 else start


def _locked_ankle(ankle: np.ndarray, h: np.ndarray, c: np.ndarray, fixed: int, at_mean: bool) -> np.ndarray:
    """ankle (B, T, 3) world m, h (B, T) lowest foot joint above rest, c (B, T) contacts -> the
    ankle target (B, T, 3): on contact frames at rest height and locked at its run's xy (the last
    context frame for runs begun before, else the run's first frame or, ``at_mean``, its mean);
    elsewhere the network's, lifted onto the floor where under it (module doc, step 2)."""
    B, T = c.shape
    A = ankle.copy()
    A[..., 2] += np.where(c, -h, np.maximum(-h, 0.0))
    start = _run_start(c, fixed)
    lock_xy = np.take_along_axis(A[..., :2], start[..., None], axis=1)
    if at_mean:  # a run begun in this episode is locked at its mean, not its first, position
        key = (np.arange(B)[:, None] * T + start)[c]
        n = np.bincount(key, minlength=B * T)
        mean = np.stack([np.bincount(key, A[..., i][c], minlength=B * T) / np.maximum(n, 1) for i in range(2)], -1)
        own = (start >= fixed) if fixed > 0 else np.ones_like(c)
        lock_xy = np.where((c & own)[..., None], mean.reshape(B, T, 2)[np.arange(B)[:, None], start], lock_xy)
    A[..., :2] = np.where(c[..., None], lock_xy, A[..., :2])
    return A


def _release_out_of_reach(c: np.ndarray, hip: np.ndarray, target: np.ndarray, reach: float, fixed: int) -> np.ndarray:
    """(B, T) contacts with every run ended at its first new frame (>= ``fixed``) whose locked ankle
    ``target`` (B, T, 3) is farther than ``reach`` (thigh + shin + slack, m) from the ``hip`` (B, T, 3): the
    leg cannot hold the lock there (the IK would drag the foot off it, up into the air), so the
    person has lifted that foot; from there it swings to its next contact."""
    B, T = c.shape
    far = c & (np.linalg.norm(target - hip, axis=-1) > reach)
    far[:, :fixed] = False
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    last_far = np.maximum.accumulate(np.where(far, t, -1), axis=1)
    return c & ~(last_far >= _run_start(c, fixed))


def _replant_unweighted(c: np.ndarray, ankle: np.ndarray, target: np.ndarray, seated: np.ndarray, distance: float,
                        gap: int, fixed: int) -> np.ndarray:
    """(B, T) contacts with a run ended at its first new frame (>= ``fixed``) where the body is
    ``seated`` (B, T) and the network's ankle (B, T, 3) is more than ``distance`` m (horizontally)
    from the run's locked ``target`` (B, T, 3): the foot is lifted for ``gap`` frames and planted
    again from there (a new run, locked where the network holds it). A seated person moves their
    unweighted feet; the lock carried over from the last step would hold them where they landed."""
    B, T = c.shape
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    drift = c & seated & (np.linalg.norm(target[..., :2] - ankle[..., :2], axis=-1) > distance) & (t >= fixed)
    start = _run_start(c, fixed)
    key = np.where(drift, start, -1)
    out = c.copy()
    for b, f in zip(*np.nonzero(drift)):
        if key[b, f] < 0:
            continue
        first = f  # the run's first drifting frame: lift here; the rest of the run is a new one
        out[b, first:first + gap] = False
        key[b, (start[b] == start[b, first]) & c[b]] = -1  # one cut per run and pass
    return out


def _lift_replants(target: np.ndarray, low: np.ndarray, lifted: np.ndarray, lift: float) -> np.ndarray:
    """Ankle targets (B, T, 3) with the lowest foot joint (``low`` (B, T), m above rest on the targets)
    raised to at least ``lift`` x sin(pi u) on each run of ``lifted`` (B, T) frames, u = (i + 1) / (n + 1)
    for the i-th of its n frames."""
    B, T = lifted.shape
    t = np.broadcast_to(np.arange(T)[None], (B, T))
    begins = lifted & ~np.concatenate([np.zeros((B, 1), bool), lifted[:, :-1]], 1)
    start = np.maximum.accumulate(np.where(begins, t, 0), axis=1)
    ends = lifted & ~np.concatenate([lifted[:, 1:], np.zeros((B, 1), bool)], 1)
    stop = np.flip(np.minimum.accumulate(np.flip(np.where(ends, t, T), 1), axis=1), 1)
    u = (t - start + 1) / np.maximum(stop - start + 2, 2)
    raise_by = np.where(lifted, np.maximum(lift * np.sin(np.pi * u) - low, 0.0), 0.0)
    out = target.copy()
    out[..., 2] += raise_by
    return out


def knee_out_of_scene(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, outward: np.ndarray, sdf, radius: float,
                      max_angle: float = np.pi / 3, steps: int = 12) -> np.ndarray:
    """Knees (B, T, 3) world m turned outward (towards ``outward`` (B, T, 3): from the other hip to
    this one) about their hip-ankle axis, bone lengths kept, by the least angle that puts them
    ``radius`` m clear of the scene: the depth is sampled at ``steps`` angles up to ``max_angle``
    rad and its first zero crossing interpolated linearly (so the angle follows the depth smoothly
    over frames); where no angle clears, the clearest one. A knee that a foot lifted onto the floor
    bent forward into a wall or a table splays outward, as a person's does. sdf: ``SceneSDF``."""
    import torch

    f = ankle - hip
    f = f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), 1e-9)
    centre = hip + ((knee - hip) * f).sum(-1, keepdims=True) * f
    u = knee - centre  # (B, T, 3) from the circle's centre to the knee
    e2 = np.cross(f, u)  # the circle's tangent at the knee, |e2| = |u|
    e2 *= np.where((e2 * outward).sum(-1) < 0, -1.0, 1.0)[..., None]  # turning outward
    angle = max_angle * np.arange(steps + 1) / steps  # (K,)
    cand = centre[..., None, :] + np.cos(angle)[:, None] * u[..., None, :] + np.sin(angle)[:, None] * e2[..., None, :]
    depth = radius - sdf(torch.as_tensor(cand, dtype=torch.float32)).double().numpy()  # (B, T, K)
    clear = depth <= 0
    k = np.where(clear.any(-1), np.argmax(clear, -1), np.argmin(depth, -1))  # first clear, else the clearest
    d1 = np.take_along_axis(depth, k[..., None], -1)[..., 0]
    d0 = np.take_along_axis(depth, np.maximum(k - 1, 0)[..., None], -1)[..., 0]
    frac = np.where((k > 0) & (d1 <= 0), d0 / np.maximum(d0 - d1, 1e-9), 1.0)  # the crossing between k - 1 and k
    turn = np.where(k > 0, angle[np.maximum(k - 1, 0)] + frac * (max_angle / steps), 0.0)
    return centre + np.cos(turn)[..., None] * u + np.sin(turn)[..., None] * e2


def clean_feet(joints: np.ndarray, lengths: np.ndarray, fps: float, fixed: int = 0,
               config: FootCleanupConfig = FootCleanupConfig(), sdf=None, seated: np.ndarray | None = None) -> np.ndarray:
    """joints (B, T, 24, 3) world m on bone ``lengths`` (24,) -> cleaned copy; frames < ``fixed``
    (the context) are kept and seed the locks. sdf: a ``SceneSDF`` of the scene (floor excluded) or
    None; with it, planted and swinging feet are moved out of furniture (``out_of_scene``, core
    radii). seated: (B, T) bool, the frames of a sit phase (their feet are re-planted where the
    network moves them, ``FootCleanupConfig.replant_distance``), or None. See the module doc."""
    J = episode_joints(joints, fixed)
    B, T = J.shape[:2]
    contact = foot_contacts(J, fps, config)
    if config.support:
        l, r = LEG_CHAINS
        leg = 0.5 * (lengths[l[1]] + lengths[l[2]] + lengths[r[1]] + lengths[r[2]])
        contact = support_foot(contact, J, float(leg), fps, fixed, margin=config.support_margin,
                               upright=config.support_upright, speed_weight=config.support_speed_weight)
    for s, (hip, knee, ankle, toe) in enumerate(LEG_CHAINS):
        c = contact[..., s]
        h = _foot_height(J, ankle, toe)  # (B, T)
        A = _locked_ankle(J[:, :, ankle], h, c, fixed, config.lock_at_mean)
        reach = float(lengths[knee] + lengths[ankle]) + config.reach_slack
        for _ in range(config.reach_passes):  # a lock the leg cannot reach ends its run; the rest re-locks
            cut = _release_out_of_reach(c, J[:, :, hip], A, reach, fixed)
            if (cut == c).all():
                break
            c = cut
            A = _locked_ankle(J[:, :, ankle], h, c, fixed, config.lock_at_mean)
        before_replant = c
        if config.replant_distance > 0 and seated is not None:
            for _ in range(config.reach_passes + 1):  # a re-planted run may drift again from its new lock
                cut = _replant_unweighted(c, J[:, :, ankle], A, seated, config.replant_distance,
                                          config.replant_frames, fixed)
                if (cut == c).all():
                    break
                c = cut
                A = _locked_ankle(J[:, :, ankle], h, c, fixed, config.lock_at_mean)
        delta = A - J[:, :, ankle]  # (B, T, 3) correction; outside runs only the floor lift
        idx, w = _fade(c, fixed, config.blend)
        run_delta = np.take_along_axis(delta, idx[..., None], axis=1) * w[..., None]
        corr = np.where(c[..., None], delta, run_delta)  # free frames: the faded lock, at least the floor lift
        corr[..., 2] = np.where(c, delta[..., 2], np.maximum(run_delta[..., 2], delta[..., 2]))
        corr[:, :fixed] = 0.0
        target = J[:, :, ankle] + corr
        target = _swing_paths(J[:, :, ankle], target, h, c, fixed, config)
        if config.replant_lift > 0 and (before_replant & ~c).any():
            target = _lift_replants(target, h + target[..., 2] - J[:, :, ankle, 2], before_replant & ~c,
                                    config.replant_lift)
        toe_off = J[:, :, toe] - J[:, :, ankle]
        if sdf is not None:
            target[:, fixed:] = out_of_scene(target[:, fixed:], toe_off[:, fixed:], sdf,
                                             (float(JOINT_CORE_RADIUS[ankle]), float(JOINT_CORE_RADIUS[toe])), ~c[:, fixed:],
                                             config.scene_iters, config.scene_max_step)
        new_knee, new_ankle = two_bone_positions(J[:, :, hip], J[:, :, knee], target,
                                                 float(lengths[knee]), float(lengths[ankle]))
        if sdf is not None:  # a knee the re-solve bent into furniture turns outward
            other = LEG_CHAINS[1 - s][0]
            new_knee[:, fixed:] = knee_out_of_scene(J[:, fixed:, hip], new_knee[:, fixed:], new_ankle[:, fixed:],
                                                    J[:, fixed:, hip] - J[:, fixed:, other], sdf, float(JOINT_CORE_RADIUS[knee]),
                                                    config.knee_max_angle, config.knee_steps)
        solve = (np.abs(target - J[:, :, ankle]).max(-1) > 1e-9)[..., None]  # frames without a correction keep their leg
        J[:, :, knee] = np.where(solve, new_knee, J[:, :, knee])
        J[:, :, ankle] = np.where(solve, new_ankle, J[:, :, ankle])
        J[:, :, toe] = np.where(solve, new_ankle + toe_off, J[:, :, toe])
    return J.astype(np.asarray(joints).dtype)
