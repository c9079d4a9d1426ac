"""Per-room take scripting: a random sequence of activities chosen from what a room contains.

A *take* is one continuous performance of one actor in one room: idle -> walk (planned path to an
object's approach point) -> interact -> walk -> ... Every primitive starts and ends in the canonical
standing state (``locomotion.standing_state``), so concatenation has no jumps. The take carries
the pose of every dynamic object on every frame (held where it was left when not moved), action
labels with progress (``trumans.actions``), contacts from geometry (``trumans.contacts.rule``), and
joints by FK of the rotations (exact bone lengths). Each take draws a new actor: bone-length scale
0.9-1.1 (plus +-2 % symmetric per-bone proportions), walking speed, timing and style noise.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from trumans.actions import ActionInterval, labels_from_intervals
from trumans.intervals import runs
from trumans.contacts.rule import CONTACT_THRESHOLD, contact_rule
from trumans.sequence import ObjectTrack, Sequence
from trumans.skeleton import FEET, JOINT_NAMES, NUM_JOINTS, WRISTS, forward_kinematics, heading, rest_offsets
from . import hands
from .motion import Motion, concat_motions
from .room import RoomContext
from .vocab import SYNTH_ACTIONS

__all__ = ["Skip", "Take", "TakeState", "TakeSnapshot", "draw_actor"]



class Skip(Exception):
    """An activity cannot be performed from the current state (no path, out of reach, ...)."""


@dataclass
class Take:
    """One scripted take. sequence: the clip (scene id filled by the builder); offsets: (24, 3) the
    actor's rest offsets (m); penetration: (T, 24) body penetration into the scene per joint (m);
    foot_floor: (T, 2) bool left/right foot joint in contact with the floor; grasp_gaps: (n,) m,
    palm point to held-object-surface distance on every (grasp frame, hand), see ``_grasp_gaps``."""

    sequence: Sequence
    offsets: np.ndarray
    penetration: np.ndarray
    foot_floor: np.ndarray
    grasp_gaps: np.ndarray
    done: dict[str, int] = field(default_factory=dict)  # activity -> times performed
    skipped: dict[str, list[str]] = field(default_factory=dict)  # activity -> reasons it was skipped


class TakeSnapshot(NamedTuple):
    """What ``TakeState.restore`` needs to roll a take back to where ``TakeState.snapshot`` was taken."""

    parts: int
    frames: int
    pos: np.ndarray
    yaw: float
    poses: dict[str, np.ndarray]
    grasped: list[tuple[np.ndarray, int, str]]


@dataclass
class TakeState:
    """The actor and the room during a take: the actor's rest ``offsets`` (24, 3) m and walking
    ``speed`` (m/s), the pelvis xy ``pos`` (2,) m and heading ``yaw`` (rad) where the last motion
    ended, and the current world pose (4, 4) of every dynamic object (``poses``; the poses at
    construction are kept as ``initial``).

    Activities add motion with ``append``; a failed activity is rolled back with ``snapshot`` /
    ``restore``; ``finish`` turns the motions into a ``Take``."""

    offsets: np.ndarray
    speed: float
    pos: np.ndarray
    yaw: float
    poses: dict[str, np.ndarray]
    parts: list[Motion] = field(default_factory=list)
    frames: int = 0
    grasped: list[tuple[np.ndarray, int, str]] = field(default_factory=list)  # (take frames, wrist joint, object)
    initial: dict[str, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.initial = {n: p.copy() for n, p in self.poses.items()}

    def append(self, m: Motion, grasp_object: dict[int, str] | None = None) -> None:
        """Add a motion; update position, heading and the poses of the objects it moved.
        ``grasp_object``: wrist joint -> name of the object that hand holds in ``m`` (its grasp
        frames are recorded for ``Take.grasp_gaps``)."""
        for hand, name in (grasp_object or {}).items():
            g = m.grasp.get(hand)
            if g is not None and g.any():
                self.grasped.append((self.frames + np.flatnonzero(g), hand, name))
        for name, track in m.objects.items():
            if name not in self.poses:
                raise ValueError(f"motion moves unknown object {name!r}")
            last = track[np.isfinite(track).all(axis=(1, 2))]
            if len(last):
                self.poses[name] = last[-1].copy()
        self.parts.append(m)
        self.frames += m.num_frames
        j = m.joints()[-1]
        self.pos = m.root[-1, :2].copy()
        self.yaw = float(heading(j))

    def snapshot(self) -> TakeSnapshot:
        """The state as it is now (see ``restore``)."""
        return TakeSnapshot(len(self.parts), self.frames, self.pos.copy(), self.yaw, dict(self.poses),
                            list(self.grasped))

    def restore(self, snap: TakeSnapshot) -> None:
        """Roll back to ``snap``: the motions appended since are dropped."""
        self.frames, self.pos, self.yaw, self.poses, self.grasped = (snap.frames, snap.pos, snap.yaw, snap.poses,
                                                                     snap.grasped)
        del self.parts[snap.parts:]

    def motion(self) -> Motion:
        """All motions so far, concatenated."""
        return concat_motions(self.parts)

    def object_tracks(self, ctx: RoomContext) -> dict[str, np.ndarray]:
        """(T, 4, 4) world pose of every dynamic object over ``motion()`` (see ``_fill_tracks``)."""
        return _fill_tracks(ctx, self.motion(), self.initial)

    def finish(self, ctx: RoomContext) -> Take:
        """The take: the parts concatenated, with labels, object tracks, contacts and metric terms."""
        return _finish(ctx, self)


def draw_actor(rng: np.random.Generator) -> np.ndarray:
    """A random actor's rest offsets (24, 3) m: overall scale U(0.9, 1.1) times symmetric per-bone
    proportions U(0.98, 1.02)."""
    scale = rng.uniform(0.9, 1.1)
    per = rng.uniform(0.98, 1.02, NUM_JOINTS)
    for j, n in enumerate(JOINT_NAMES):  # left/right bones share their proportion
        if n.startswith("right_"):
            per[j] = per[JOINT_NAMES.index("left_" + n[6:])]
    return rest_offsets(scale * per)


def _fill_tracks(ctx: RoomContext, motion: Motion, init: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """(T, 4, 4) pose of every dynamic object: moved where a primitive gave it, else held at the
    last known pose (initially the scene pose)."""
    T = motion.num_frames
    out = {}
    for name, obj in ctx.scene.objects.items():
        if not obj.dynamic:
            continue
        tr = motion.objects.get(name)
        if tr is None:
            out[name] = np.broadcast_to(init[name], (T, 4, 4)).copy()
            continue
        known = np.isfinite(tr).all(axis=(1, 2))
        idx = np.where(known, np.arange(T), -1)
        idx = np.maximum.accumulate(idx)  # last known frame at or before t
        filled = np.where((idx >= 0)[:, None, None], tr[np.maximum(idx, 0)], init[name])
        out[name] = filled
    return out


def _finish(ctx: RoomContext, st: TakeState) -> Take:
    m = st.motion()
    T = m.num_frames
    joints, G = forward_kinematics(m.rot, m.root, m.offsets)
    tracks = _fill_tracks(ctx, m, st.initial)
    res = ctx.contacts.query(joints, tracks)
    con = contact_rule(joints, res, threshold=CONTACT_THRESHOLD, global_rot=G)
    # Floor contact of a foot: in contact with a surface point at floor level (the floor plane or
    # the room's floor mesh, whichever is nearer).
    foot_floor = con.contact[:, list(FEET)] & (np.abs(con.closest[:, list(FEET), 2]) < 0.005)
    gaps = _grasp_gaps(ctx, joints, tracks, st.grasped)
    labels = labels_from_intervals(_merge_runs(m.actions, T), list(SYNTH_ACTIONS), T)
    grasp = np.zeros((T, 2), dtype=bool)
    for k, h in enumerate(WRISTS):
        if h in m.grasp:
            grasp[:, k] = m.grasp[h]
    seq = Sequence(
        joints=joints.astype(np.float32),
        fps=ctx.fps,
        rotations=m.rotations_6d(),
        root_pos=m.root.astype(np.float32),
        actions=labels,
        action_names=list(SYNTH_ACTIONS),
        contacts=con.contact,
        scene=ctx.scene.name,
        objects={n: ObjectTrack(pose=p.astype(np.float32), category=ctx.scene.objects[n].category)
                 for n, p in tracks.items()},
        extra={"offsets": m.offsets.astype(np.float32), "foot_contact": m.foot_contact.astype(bool),
               "grasp": grasp},
    )
    return Take(seq, m.offsets, con.penetration.astype(np.float64), foot_floor, gaps)


def _merge_runs(intervals: list[ActionInterval], T: int) -> list[ActionInterval]:
    """Merge intervals of the same action that touch or overlap (e.g. the 'carry' that ends a
    pick-up and the 'carry' of the walk after it), so progress runs 0 -> 1 once over the run: the
    runs (``trumans.contacts.intervals.runs``, half-open) of each action's frames over T frames."""
    frames: dict[str, np.ndarray] = {}
    for iv in intervals:
        frames.setdefault(iv.name, np.zeros(T, dtype=bool))[iv.start:iv.end] = True
    out = [ActionInterval(name, s, e) for name, m in frames.items() for s, e in runs(m)]
    return sorted(out, key=lambda v: (v.start, v.name))


def _grasp_gaps(ctx: RoomContext, joints: np.ndarray, tracks: dict[str, np.ndarray],
                grasped: list[tuple[np.ndarray, int, str]]) -> np.ndarray:
    """Distance (m) from the hand's palm point (``hands.palm_points``: midpoint of wrist and index1;
    the primitives put it ``hands.PALM_GAP`` = 1 cm off the surface) to the surface of the object it
    holds, on every (grasp frame, hand): |signed distance| in the object's frame at its pose."""
    out = []
    palms = hands.palm_points(joints)  # (T, 2, 3)
    for frames, wrist, name in grasped:
        sd = ctx.contacts.dynamic.get(name)
        if sd is None or len(frames) == 0:
            continue
        pose = tracks[name][frames]
        p = palms[frames, 0 if wrist == hands.WRIST["left"] else 1]
        inv = np.linalg.inv(pose)
        local = np.einsum("tij,tj->ti", inv[:, :3, :3], p) + inv[:, :3, 3]
        out.append(np.abs(sd.query(local).signed.astype(np.float64)))
    return np.concatenate(out) if out else np.zeros(0)
