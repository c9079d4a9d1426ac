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
from typing import Callable

import numpy as np

from scenes.occupancy import OccupancyGrid
from scenes.scene import Scene
from scenes.walkability import NoPathError, WalkMap, nearest_walkable, plan_path, walkable_map

from trumans.actions import ActionInterval, labels_from_intervals
from trumans.contacts.rule import CONTACT_THRESHOLD, JOINT_RADIUS, ContactScene, contact_rule
from trumans.sequence import ObjectTrack, Sequence
from trumans.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, forward_kinematics, heading, rest_offsets
from . import hands, hands_desk, hands_furniture, locomotion, posture
from .motion import Motion, concat_motions
from .vocab import SYNTH_ACTIONS

__all__ = ["Take", "RoomContext", "draw_actor", "script_room", "script_take", "ACTIVITIES"]

MAX_WALK_PENETRATION = 0.015  # m, a planned walk that brushes furniture deeper than this is rejected
MAX_PENETRATION = 0.025  # m, an interaction deeper than this into the scene is rejected (activity skipped)
_HANDS = (JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"])
_FEET = (JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])


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


@dataclass
class RoomContext:
    """What a take needs to know about its room (built once per room).

    ``plans``: walk maps for path planning with decreasing clearance (tried in order);
    ``check``: a fine walk map with the minimum clearance the walking pelvis must keep (the gait
    rounds the planned corners, so a path is accepted only if the generated pelvis track stays on
    it); ``contacts``: the contact geometry of the scene."""

    scene: Scene
    plans: list[WalkMap]
    check: WalkMap
    contacts: ContactScene
    fps: float = 30.0

    def penetration(self, m: Motion, poses: dict[str, np.ndarray]) -> float:
        """Deepest body penetration (m, see ``trumans.contacts.rule.body_penetration``) of motion ``m``
        with the dynamic objects at ``poses`` (or where ``m`` moves them)."""
        return self.worst_penetration(m, poses)[0]

    def worst_penetration(self, m: Motion, poses: dict[str, np.ndarray]) -> tuple[float, str]:
        """(deepest body penetration (m), 'joint into object at frame t') of motion ``m``."""
        tracks = {n: (m.objects[n] if n in m.objects and np.isfinite(m.objects[n]).all() else p[None])
                  for n, p in poses.items()}
        joints, G = forward_kinematics(m.rot, m.root, m.offsets)
        res = self.contacts.query(joints, tracks)
        d = contact_rule(joints, res, global_rot=G).penetration
        t, j = np.unravel_index(int(d.argmax()), d.shape)
        return float(d[t, j]), f"{JOINT_NAMES[j]} into {res.names[res.mesh_index[t, j]]} at frame {t}/{len(d)}"

    @property
    def walk(self) -> WalkMap:
        """The most permissive planning map."""
        return self.plans[-1]

    @staticmethod
    def build(scene: Scene, occ: OccupancyGrid, fps: float = 30.0,
              radii: tuple[float, ...] = (0.4, 0.3, 0.22), check_radius: float = 0.15) -> "RoomContext":
        """Planning maps at body radii ``radii`` (m), coarsened 2x (a coarse cell is walkable when
        its 2x2 fine cells are) so that path planning stays fast; the check map at ``check_radius``."""
        plans = []
        for r in radii:
            wm = walkable_map(occ, body_radius=r)
            w = wm.walkable
            nx, ny = (w.shape[0] // 2) * 2, (w.shape[1] // 2) * 2
            coarse = w[:nx, :ny].reshape(nx // 2, 2, ny // 2, 2).all(axis=(1, 3))
            plans.append(WalkMap(coarse, wm.origin + 0.5 * wm.cell, 2 * wm.cell))
        return RoomContext(scene, plans, walkable_map(occ, body_radius=check_radius), ContactScene(scene), fps)


@dataclass
class _State:
    """The actor and the room during a take: pelvis xy, heading, current object poses."""

    offsets: np.ndarray
    speed: float
    pos: np.ndarray
    yaw: float
    poses: dict[str, np.ndarray]
    parts: list[Motion] = field(default_factory=list)
    frames: int = 0
    grasped: list[tuple[np.ndarray, int, str]] = field(default_factory=list)  # (take frames, wrist joint, object)

    def append(self, m: Motion, grasp_object: dict[int, str] | None = None) -> None:
        """Add a motion; update position, heading and the poses of the objects it moved."""
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


def draw_actor(rng: np.random.Generator) -> np.ndarray:
    """A random actor's rest offsets (24, 3) m: overall scale U(0.9, 1.1) times symmetric per-bone
    proportions U(0.98, 1.02)."""
    scale = rng.uniform(0.9, 1.1)
    per = rng.uniform(0.98, 1.02, NUM_JOINTS)
    for j, n in enumerate(JOINT_NAMES):  # left/right bones share their proportion
        if n.startswith("right_"):
            per[j] = per[JOINT_NAMES.index("left_" + n[6:])]
    return rest_offsets(scale * per)


def _world(pose: np.ndarray, p_local) -> np.ndarray:
    p = np.asarray(p_local, dtype=np.float64)
    if p.shape == (2,):
        p = np.array([p[0], p[1], 0.0])
    return pose[:3, :3] @ p + pose[:3, 3]


def _yaw_of(pose: np.ndarray) -> float:
    return float(np.arctan2(pose[1, 0], pose[0, 0]))


def walk_to(ctx: RoomContext, st: _State, rng: np.random.Generator, goal: np.ndarray, goal_yaw: float,
            base_pose: str = "stand") -> Motion | None:
    """A walk (or a turn in place) from the actor's position to pelvis xy ``goal`` facing
    ``goal_yaw``; None when already there. The path is planned on the walk map to the walkable
    cell nearest the goal, which is then appended as the final waypoint (approach points lie close
    to furniture). Maps with more clearance are tried first; a walk whose pelvis track leaves the
    check map (away from its two ends) is rejected. Raises Skip when no map gives a clean walk."""
    goal = np.asarray(goal, dtype=np.float64)[:2]
    if np.linalg.norm(goal - st.pos) < 0.08:
        if abs(float(locomotion.wrap_angle(goal_yaw - st.yaw))) < np.radians(8):
            return None
        return locomotion.turn(st.offsets, st.pos, st.yaw, goal_yaw, rng, fps=ctx.fps, base_pose=base_pose)
    speed = float(np.clip(st.speed * rng.uniform(0.9, 1.1), 0.5, 1.8))
    reason = "no walkable path"
    for wm in ctx.plans:
        try:
            start = st.pos if wm.query(st.pos) else nearest_walkable(wm, st.pos)
            end = goal if wm.query(goal) else nearest_walkable(wm, goal)
            if np.linalg.norm(end - goal) > 0.6 or np.linalg.norm(start - st.pos) > 0.6:
                reason = f"goal {goal.round(2).tolist()} is too far from walkable floor"
                continue
            path = plan_path(wm, start, end, spacing=0.6)
        except NoPathError as e:
            reason = str(e)
            continue
        path = np.concatenate([st.pos[None], path, goal[None]])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(path, axis=0), axis=1) > 0.02])
        path = path[keep]
        if len(path) < 2:
            return locomotion.turn(st.offsets, st.pos, st.yaw, goal_yaw, rng, fps=ctx.fps, base_pose=base_pose)
        m = locomotion.walk(path, st.offsets, rng, speed=speed, fps=ctx.fps, start_yaw=st.yaw, end_yaw=goal_yaw,
                            base_pose=base_pose)
        xy = m.root[:, :2]
        away = (np.linalg.norm(xy - st.pos, axis=1) > 0.35) & (np.linalg.norm(xy - goal, axis=1) > 0.35)
        if not ctx.check.query(xy[away]).all():
            reason = "the walk leaves the walkable floor"
            continue
        depth, where = ctx.worst_penetration(m, st.poses)
        if depth <= MAX_WALK_PENETRATION:
            return m
        reason = f"the walk brushes furniture by {100 * depth:.1f} cm ({where})"
    raise Skip(reason)


def _idle(ctx: RoomContext, st: _State, rng: np.random.Generator, lo: float = 0.5, hi: float = 2.5) -> Motion:
    return locomotion.stand(st.offsets, st.pos, st.yaw, int(rng.uniform(lo, hi) * ctx.fps), rng, fps=ctx.fps)


# ----------------------------------------------------------------------------- activities
# Each activity: (name, objects it applies to (category filter), run(ctx, st, rng, object name)).

Activity = Callable[[RoomContext, _State, np.random.Generator, str], None]
ACTIVITIES: dict[str, tuple[tuple[str, ...], Activity]] = {}


def activity(name: str, categories: tuple[str, ...]):
    def deco(fn: Activity) -> Activity:
        ACTIVITIES[name] = (categories, fn)
        return fn
    return deco


@activity("wander", ())
def _wander(ctx: RoomContext, st: _State, rng: np.random.Generator, _: str) -> None:
    """Walk to a random walkable floor point and stand there a moment."""
    cells = np.argwhere(ctx.plans[0].walkable)
    for _try in range(10):
        goal = ctx.plans[0].centers(cells[rng.integers(len(cells))])
        if np.linalg.norm(goal - st.pos) > 1.0:
            break
    m = walk_to(ctx, st, rng, goal, float(rng.uniform(-np.pi, np.pi)))
    if m is not None:
        st.append(m)
    st.append(_idle(ctx, st, rng))


def _check_clean(ctx: RoomContext, st: _State, m: Motion, what: str) -> Motion:
    """Raise Skip when motion ``m`` penetrates the scene deeper than MAX_PENETRATION."""
    depth, where = ctx.worst_penetration(m, st.poses)
    if depth > MAX_PENETRATION:
        raise Skip(f"{what} penetrates the scene by {100 * depth:.1f} cm ({where})")
    return m


def _rest_lift(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, surface_z: float, joints: list[int]) -> float:
    """How far (m) a resting state must be raised so that the body surface of ``joints`` (joint
    height minus its contact radius) is not below ``surface_z``."""
    P, _ = forward_kinematics(rot[None], root[None], offsets)
    gap = P[0, joints, 2] - surface_z - JOINT_RADIUS[joints]
    return float(max(0.0, -gap.min()))


_SEAT_JOINTS = [JOINT_INDEX[n] for n in ("pelvis", "left_hip", "right_hip")]


def _seat(obj, pose: np.ndarray, offsets: np.ndarray, rng: np.random.Generator,
          near: np.ndarray | None = None) -> tuple[np.ndarray, float, np.ndarray]:
    """World (seat point raised so the seated body rests on the surface, sit yaw, stand point): a
    random place of the seat, or the one nearest world xy ``near``."""
    centers = [_world(pose, c) for c in (obj.meta.get("seat_centers") or [obj.meta["seat_center"]])]
    if near is None:
        c = centers[rng.integers(len(centers))]
    else:
        c = min(centers, key=lambda p: float(np.linalg.norm(p[:2] - np.asarray(near)[:2])))
    yaw = _yaw_of(pose) + float(obj.meta["sit_yaw"])
    stand = c[:2] + (_world(pose, obj.meta["approach"]) - _world(pose, obj.meta["seat_center"]))[:2]
    try:
        rot, root = posture.seated_state(offsets, c, yaw, stand)
        c = c + [0.0, 0.0, _rest_lift(rot, root, offsets, float(c[2]), _SEAT_JOINTS)]
        posture.seated_state(offsets, c, yaw, stand)
    except ValueError as e:  # this actor's feet cannot reach the floor from this seat
        raise Skip(str(e)) from e
    return c, yaw, stand


def _posture_change(ctx: RoomContext, st: _State, rng: np.random.Generator, fn, args: tuple, what: str) -> Motion:
    """``fn(*args, rng, fps=..., arm_swing=...)`` (sit_down / stand_up) with the arms swinging forward
    for balance, or held back where they would hit something in front (a desk); Skip if still unclean."""
    m = fn(*args, rng, fps=ctx.fps)
    if ctx.worst_penetration(m, st.poses)[0] <= MAX_PENETRATION:
        return m
    return _check_clean(ctx, st, fn(*args, rng, fps=ctx.fps, arm_swing=0.0), what)


def _sit_on(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str,
            seated: Callable[[np.ndarray, float, np.ndarray], None] | None = None,
            near: np.ndarray | None = None) -> None:
    obj = ctx.scene.objects[name]
    pose = st.poses.get(name, obj.pose)
    seat, yaw, stand = _seat(obj, pose, st.offsets, rng, near)
    m = walk_to(ctx, st, rng, stand, yaw)
    if m is not None:
        st.append(m)
    st.append(_posture_change(ctx, st, rng, posture.sit_down, (st.offsets, seat, yaw, stand), "sit_down"))
    if seated is None:
        n = int(rng.uniform(2.0, 8.0) * ctx.fps)
        st.append(_check_clean(ctx, st, posture.sit(st.offsets, seat, yaw, stand, n, rng, fps=ctx.fps), "sit"))
    else:
        seated(seat, yaw, stand)
    st.append(_posture_change(ctx, st, rng, posture.stand_up, (st.offsets, seat, yaw, stand), "stand_up"))


@activity("sit", ("chair", "stool", "sofa", "bed"))
def _sit(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Walk to a seat, sit down, sit a while, stand up."""
    _sit_on(ctx, st, rng, name)


@activity("lie", ("bed", "sofa"))
def _lie(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Walk to a bed or sofa, sit on its edge, lie down, lie a while, get up, stand up. The body
    lies along the surface (``lie_center``, ``lie_yaw``, ``lie_length`` meta) where
    ``posture.fit_lying`` puts it: straight, or knees up on a short sofa; the seat place nearest
    the lying pelvis is used."""
    obj = ctx.scene.objects[name]
    pose = st.poses.get(name, obj.pose)
    ly = _yaw_of(pose) + float(obj.meta["lie_yaw"])
    try:
        shift, reach = posture.fit_lying(st.offsets, float(obj.meta["lie_length"]))
    except ValueError as e:
        raise Skip(f"{name}: {e}") from e
    lc = _world(pose, obj.meta["lie_center"]) + shift * np.array([np.cos(ly), np.sin(ly), 0.0])

    def lying(seat: np.ndarray, yaw: float, stand: np.ndarray) -> None:
        kw = dict(sit_yaw=yaw, stand_pos=stand, fps=ctx.fps, leg_reach=reach)
        st.append(_check_clean(ctx, st, posture.lie_down(st.offsets, lc, ly, seat, rng, **kw), "lie_down"))
        n = int(rng.uniform(3.0, 10.0) * ctx.fps)
        st.append(_check_clean(ctx, st, posture.lie(st.offsets, lc, ly, n, rng, fps=ctx.fps, leg_reach=reach),
                               "lie"))
        st.append(_check_clean(ctx, st, posture.get_up(st.offsets, lc, ly, seat, rng, **kw), "get_up"))

    _sit_on(ctx, st, rng, name, seated=lying, near=lc)


_SMALL = ("bottle", "cup", "phone", "book", "pen", "vase")
_SURFACES = ("table", "desk", "cabinet")


def _stand_base(ctx: RoomContext, st: _State, rng: np.random.Generator, kind: str) -> Motion:
    """Standing base motion of natural length for hand primitive ``kind``."""
    return locomotion.stand(st.offsets, st.pos, st.yaw, hands.nominal_frames(kind, rng, ctx.fps), rng, fps=ctx.fps)


def _approach(obj, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """World pelvis xy and heading from which a person interacts with ``obj`` at ``pose``."""
    return _world(pose, obj.meta["approach"])[:2], _yaw_of(pose) + float(obj.meta["approach_yaw"])


def _approach_point(ctx: RoomContext, st: _State, name: str, target: np.ndarray) -> tuple[np.ndarray, float]:
    """Where to stand to handle something at world ``target`` on object ``name``'s support: the
    support's approach line (parallel to its front edge) at the point in front of the target."""
    obj = ctx.scene.objects[name]
    sup = ctx.scene.objects.get(str(obj.meta.get("support", ""))) if obj.category in _SMALL + (
        "keyboard", "mouse", "laptop") else obj
    if sup is None or "surface_size" not in sup.meta:
        return _approach(obj, st.poses.get(name, obj.pose))
    pose = st.poses.get(sup.name, sup.pose)
    # Surfaces face +x (scenes.furniture): stand 0.28 m in front of the front edge, facing -x.
    a = _world(pose, [0.5 * float(sup.meta["surface_size"][0]) + 0.28, 0.0])[:2]
    yaw = _yaw_of(pose) + np.pi
    along = pose[:2, 1]  # the support's local y axis (its front edge direction) in the world
    half = 0.5 * float(sup.meta["surface_size"][1]) - 0.15
    u = float(np.clip((target[:2] - a) @ along, -max(half, 0.0), max(half, 0.0)))
    return a + u * along, yaw


def _sides(ctx: RoomContext, st: _State, target: np.ndarray, rng: np.random.Generator) -> list[str]:
    """Hands to try, the one on the target's side of the body first (random when centred)."""
    rel = (target[:2] - st.pos) @ np.array([-np.sin(st.yaw), np.cos(st.yaw)])
    first = ("left" if rel > 0 else "right") if abs(rel) > 0.05 else ("left", "right")[rng.integers(2)]
    return [first, "right" if first == "left" else "left"]


def _grab(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str):
    """Walk to a small object and pick it up; returns the Hold."""
    obj = ctx.scene.objects[name]
    pose = st.poses[name]
    goal, yaw = _approach_point(ctx, st, name, pose[:3, 3])
    m = walk_to(ctx, st, rng, goal, yaw)
    if m is not None:
        st.append(m)
    last: Exception | None = None
    for side in _sides(ctx, st, pose[:3, 3], rng):
        try:
            mp, hold = hands.pick_up(_stand_base(ctx, st, rng, "pick_up"), obj, pose, side, rng)
        except hands.OutOfReach as e:
            last = e
            continue
        st.append(_check_clean(ctx, st, mp, f"pick_up {name}"), {hands.WRIST[side]: name})
        return hold
    raise Skip(f"cannot reach {name}: {last}")


def _release(ctx: RoomContext, st: _State, rng: np.random.Generator, hold, target: np.ndarray) -> None:
    try:
        m = hands.put_down(_stand_base(ctx, st, rng, "put_down"), hold, target, rng)
    except hands.OutOfReach as e:
        raise Skip(f"cannot put {hold.name} down: {e}") from e
    st.append(_check_clean(ctx, st, m, f"put_down {hold.name}"), {hands.WRIST[hold.side]: hold.name})


def _free_spot(ctx: RoomContext, st: _State, rng: np.random.Generator, support: str, moving: str) -> np.ndarray | None:
    """A world pose on ``support``'s top near its front edge, >= 12 cm from other small objects."""
    sup = ctx.scene.objects[support]
    sx, sy = sup.meta["surface_size"]
    h = float(sup.meta["surface_height"])
    others = [p[:3, 3] for n, p in st.poses.items() if n != moving and ctx.scene.objects[n].category in
              _SMALL + ("keyboard", "mouse", "laptop")]
    for _ in range(20):
        x = rng.uniform(max(sx / 2 - 0.25, -sx / 2 + 0.08), sx / 2 - 0.10)
        y = rng.uniform(-(sy / 2 - 0.12), sy / 2 - 0.12)
        pose = sup.pose @ _yaw_pose(x, y, rng.uniform(-np.pi, np.pi), h)
        if all(np.linalg.norm(pose[:2, 3] - o[:2]) > 0.12 for o in others):
            return pose
    return None


def _yaw_pose(x: float, y: float, yaw: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    T[:3, 3] = [x, y, z]
    return T


@activity("pick_place", _SMALL)
def _pick_place(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Pick a small object up, carry it to a (possibly other) table / desk / cabinet, put it down."""
    supports = [n for n, o in ctx.scene.objects.items() if o.category in _SURFACES]
    if not supports:
        raise Skip("no surface to put things on")
    dest = supports[rng.integers(len(supports))]
    target = _free_spot(ctx, st, rng, dest, name)
    if target is None:
        raise Skip(f"no free spot on {dest}")
    hold = _grab(ctx, st, rng, name)
    goal, yaw = _approach_point(ctx, st, dest, target[:3, 3])
    m = walk_to(ctx, st, rng, goal, yaw)
    if m is not None:
        st.append(_check_clean(ctx, st, hands.carry(m, hold), f"carry {name}"), {hands.WRIST[hold.side]: name})
    _release(ctx, st, rng, hold, target)


@activity("drink", ("bottle", "cup"))
def _drink(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Pick up a bottle or cup, drink, put it back where it was."""
    where = st.poses[name].copy()
    hold = _grab(ctx, st, rng, name)
    m = hands.drink(_stand_base(ctx, st, rng, "drink"), hold, ctx.scene.objects[name], rng)
    st.append(_check_clean(ctx, st, m, f"drink {name}"), {hands.WRIST[hold.side]: name})
    _release(ctx, st, rng, hold, where)


@activity("phone_call", ("phone",))
def _phone(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Pick up a phone, make a call, put it back where it was."""
    where = st.poses[name].copy()
    hold = _grab(ctx, st, rng, name)
    m = hands.phone_call(_stand_base(ctx, st, rng, "phone_call"), hold, ctx.scene.objects[name], rng)
    st.append(_check_clean(ctx, st, m, f"phone_call {name}"), {hands.WRIST[hold.side]: name})
    _release(ctx, st, rng, hold, where)


@activity("desk_work", ("keyboard",))
def _desk_work(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Sit on the desk's chair, type on the keyboard and use the mouse, stand up."""
    kb = ctx.scene.objects[name]
    desk = ctx.scene.objects.get(str(kb.meta.get("support", "")))
    if desk is None:
        raise Skip(f"{name} stands on no desk")
    goal, _ = _approach(desk, desk.pose)
    chairs = [(np.linalg.norm(_approach(o, st.poses[n])[0] - goal), n) for n, o in ctx.scene.objects.items()
              if o.category == "chair"]
    chairs = [c for c in chairs if c[0] < 0.3]
    if not chairs:
        raise Skip(f"no chair at {desk.name}")
    chair = min(chairs)[1]
    mice = [n for n, o in ctx.scene.objects.items() if o.category == "mouse" and o.meta.get("support") == desk.name]

    def work(seat: np.ndarray, yaw: float, stand: np.ndarray) -> None:
        def base(kind: str) -> Motion:
            n = hands.nominal_frames(kind, rng, ctx.fps)
            return posture.sit(st.offsets, seat, yaw, stand, n, rng, fps=ctx.fps)

        order = ["type"] + (["use_mouse"] if mice else [])
        if len(order) == 2 and rng.random() < 0.5:
            order.reverse()
        for kind in order:
            try:
                if kind == "type":
                    m = hands_desk.type_keyboard(base("type"), kb, st.poses[name], rng)
                    grasped = {hands.WRIST["left"]: name, hands.WRIST["right"]: name}
                else:
                    mouse = mice[0]
                    m = hands_desk.use_mouse(base("use_mouse"), ctx.scene.objects[mouse], st.poses[mouse], rng)
                    grasped = {w: mouse for w in m.grasp}
            except hands.OutOfReach as e:
                raise Skip(f"{kind} at {desk.name}: {e}") from e
            st.append(_check_clean(ctx, st, m, kind), grasped)

    _sit_on(ctx, st, rng, chair, seated=work)


def _go(ctx: RoomContext, st: _State, rng: np.random.Generator, pos: np.ndarray, yaw: float) -> None:
    m = walk_to(ctx, st, rng, pos, yaw)
    if m is not None:
        st.append(m)


def _grasps(m: Motion, name: str) -> dict[int, str]:
    return {w: name for w, g in m.grasp.items() if np.any(g)}


MIN_DOOR_ANGLE = 0.8  # rad, a door opened less than this is no use: skip the activity


@activity("door", ("door",))
def _door(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Walk to the door, pull it open stepping back, wait, push it closed stepping forwards."""
    door = ctx.scene.objects[name]
    closed = st.poses[name].copy()
    try:
        stance = hands_furniture.door_stance(st.offsets, door, closed)
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    if stance.reach < MIN_DOOR_ANGLE:
        raise Skip(f"{name} opens only {stance.reach:.2f} rad from its stance")
    angle = float(min(stance.reach, rng.uniform(0.6, 1.0) * float(door.meta["max_angle"])))  # rad
    _go(ctx, st, rng, stance.pos, stance.yaw)
    try:
        m = hands_furniture.open_door(st.offsets, door, closed, angle, rng, stance, fps=ctx.fps)
        st.append(_check_clean(ctx, st, m, f"open_door {name}"), _grasps(m, name))
        st.append(_idle(ctx, st, rng, 0.3, 1.5))
        m = hands_furniture.close_door(st.offsets, door, closed, angle, rng, stance, fps=ctx.fps)
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    st.append(_check_clean(ctx, st, m, f"close_door {name}"), _grasps(m, name))


@activity("drawer", ("drawer",))
def _drawer(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Walk to a cabinet drawer, pull it out, wait, push it closed."""
    dr = ctx.scene.objects[name]
    closed = st.poses[name].copy()
    try:
        stance = hands_furniture.drawer_stance(st.offsets, dr, closed)
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    if stance.reach < 0.12:
        raise Skip(f"{name} opens only {stance.reach:.2f} m from its stance")
    travel = float(min(stance.reach, rng.uniform(0.5, 1.0) * float(dr.meta["max_travel"])))
    _go(ctx, st, rng, stance.pos, stance.yaw)
    try:
        m = hands_furniture.open_drawer(_stand_base(ctx, st, rng, "open_drawer"), dr, closed, travel, rng,
                                        side=stance.side)
        st.append(_check_clean(ctx, st, m, f"open_drawer {name}"), _grasps(m, name))
        st.append(_idle(ctx, st, rng, 0.3, 1.5))
        m = hands_furniture.close_drawer(_stand_base(ctx, st, rng, "close_drawer"), dr, closed, travel, rng,
                                         side=stance.side)
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    st.append(_check_clean(ctx, st, m, f"close_drawer {name}"), _grasps(m, name))


def _object_clear(ctx: RoomContext, name: str, pose: np.ndarray) -> bool:
    """True when object ``name`` placed at ``pose`` intersects no static mesh / static object."""
    if ctx.contacts.static is None:
        return True
    v = ctx.scene.objects[name].mesh.vertices
    pts = v @ pose[:3, :3].T + pose[:3, 3]
    r = ctx.contacts.static.query(pts[pts[:, 2] > 0.01][None])
    return not bool(r.inside.any())


@activity("push_pull", ("chair", "stool", "table"))
def _push_pull(ctx: RoomContext, st: _State, rng: np.random.Generator, name: str) -> None:
    """Push a chair / stool / table a few decimetres along the floor, then pull it back."""
    obj = ctx.scene.objects[name]
    if not obj.dynamic or obj.dof != "slide":
        raise Skip(f"{name} does not slide")
    pose = st.poses[name].copy()
    d = float(rng.uniform(0.2, 0.4))
    try:
        hands_furniture.push_handles(obj)
    except ValueError as e:  # the object has no place to put the hands (e.g. a stool)
        raise Skip(f"cannot push {name}: {e}") from e
    try:
        pos, yaw = hands_furniture.push_stance(st.offsets, obj, pose)
        first = hands_furniture.push(st.offsets, obj, pose, d, rng, fps=ctx.fps)
        order = ("push", "pull")
        if not _slide_clear(ctx, name, first):  # e.g. a chair tucked under a desk: pull it out first
            first = hands_furniture.pull(st.offsets, obj, pose, d, rng, fps=ctx.fps)
            order = ("pull", "push")
            if not _slide_clear(ctx, name, first):
                raise Skip(f"moving {name} {d:.2f} m either way runs into the room")
    except hands.OutOfReach as e:
        raise Skip(f"cannot push {name}: {e}") from e
    _go(ctx, st, rng, pos, yaw)
    st.append(_check_clean(ctx, st, first, f"{order[0]} {name}"), _grasps(first, name))
    moved = first.objects[name][-1]
    try:
        if order[1] == "pull":
            back = hands_furniture.pull(st.offsets, obj, moved, d, rng, fps=ctx.fps)
        else:
            back = hands_furniture.push(st.offsets, obj, moved, d, rng, fps=ctx.fps)
    except hands.OutOfReach as e:
        raise Skip(f"cannot {order[1]} {name}: {e}") from e
    st.append(_check_clean(ctx, st, back, f"{order[1]} {name}"), _grasps(back, name))


def _slide_clear(ctx: RoomContext, name: str, m: Motion) -> bool:
    """The object moved by push/pull motion ``m`` ends clear of the room and the body stays on
    walkable floor."""
    return _object_clear(ctx, name, m.objects[name][-1]) and bool(ctx.check.query(m.root[:, :2]).all())


# ----------------------------------------------------------------------------- takes


def _candidates(scene: Scene) -> list[tuple[str, str]]:
    """(activity, object) pairs this room supports."""
    out = []
    for act, (cats, _) in ACTIVITIES.items():
        if not cats:
            out.append((act, ""))
            continue
        out += [(act, n) for n, o in scene.objects.items() if o.category in cats and
                (act != "push_pull" or _pushable(o))]
    return out


def _pushable(obj) -> bool:
    """A floor-sliding object with places for the hands (``hands_furniture.push_handles``)."""
    if not (obj.dynamic and obj.dof == "slide" and obj.axis is None):
        return False
    try:
        hands_furniture.push_handles(obj)
    except ValueError:
        return False
    return True


def _object_tracks(ctx: RoomContext, motion: Motion, init: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
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


def script_take(ctx: RoomContext, rng: np.random.Generator, n_frames: int, coverage: dict[str, int]) -> Take:
    """One take of at least ``n_frames`` frames (it ends after the activity that crosses it).

    ``coverage`` counts how often each activity has been performed in the room (updated): less
    performed activities are preferred, so a room shows all it affords."""
    offsets = draw_actor(rng)
    init = {n: o.pose.copy() for n, o in ctx.scene.objects.items() if o.dynamic}
    wm = next((w for w in ctx.plans if w.walkable.any()), None)
    if wm is None:
        raise ValueError(f"room {ctx.scene.name!r} has no walkable floor")
    cells = np.argwhere(wm.walkable)
    pos = wm.centers(cells[rng.integers(len(cells))])
    st = _State(offsets=offsets, speed=float(rng.uniform(0.9, 1.4)), pos=pos,
                yaw=float(rng.uniform(-np.pi, np.pi)), poses=dict(init))
    st.append(_idle(ctx, st, rng, 0.5, 2.0))
    cands = _candidates(ctx.scene)
    failures = 0
    done: dict[str, int] = {}
    skipped: dict[str, list[str]] = {}
    while st.frames < n_frames and failures < 30:
        counts = np.array([coverage.get(a, 0) for a, _ in cands], dtype=np.float64)
        w = np.exp(-1.5 * (counts - counts.min()))
        w[[i for i, (a, _) in enumerate(cands) if a == "wander"]] *= 0.3
        act, obj = cands[rng.choice(len(cands), p=w / w.sum())]
        snapshot = (len(st.parts), st.frames, st.pos.copy(), st.yaw, dict(st.poses), list(st.grasped))
        try:
            ACTIVITIES[act][1](ctx, st, rng, obj)
            coverage[act] = coverage.get(act, 0) + 1
            done[act] = done.get(act, 0) + 1
        except (Skip, hands.OutOfReach) as e:  # OutOfReach: the hand cannot reach from where the body is
            skipped.setdefault(act, []).append(f"{obj}: {e}")
            n, st.frames, st.pos, st.yaw, st.poses, st.grasped = snapshot
            del st.parts[n:]
            failures += 1
            coverage[act] = coverage.get(act, 0) + 1  # do not insist on an impossible activity
    take = _finish(ctx, st, init)
    take.done, take.skipped = done, skipped
    return take


def _finish(ctx: RoomContext, st: _State, init: dict[str, np.ndarray]) -> Take:
    """Concatenate the parts and compute labels, object tracks, contacts and metric terms."""
    m = concat_motions(st.parts)
    T = m.num_frames
    joints, G = forward_kinematics(m.rot, m.root, m.offsets)
    tracks = _object_tracks(ctx, m, init)
    res = ctx.contacts.query(joints, tracks)
    con = contact_rule(joints, res, threshold=CONTACT_THRESHOLD, global_rot=G)
    # Floor contact of a foot: in contact with a surface point at floor level (the floor plane or
    # the room's floor mesh, whichever is nearer).
    foot_floor = con.contact[:, list(_FEET)] & (np.abs(con.closest[:, list(_FEET), 2]) < 0.005)
    gaps = _grasp_gaps(ctx, joints, tracks, st.grasped)
    labels = labels_from_intervals(_merge_runs(m.actions), list(SYNTH_ACTIONS), T)
    grasp = np.zeros((T, 2), dtype=bool)
    for k, h in enumerate(_HANDS):
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


def _merge_runs(intervals: list[ActionInterval]) -> list[ActionInterval]:
    """Merge intervals of the same action that touch or overlap (e.g. the 'carry' that ends a
    pick-up and the 'carry' of the walk after it), so progress runs 0 -> 1 once over the run."""
    out: list[ActionInterval] = []
    for iv in sorted(intervals, key=lambda v: (v.name, v.start)):
        if out and out[-1].name == iv.name and iv.start <= out[-1].end + 1:
            out[-1] = ActionInterval(iv.name, out[-1].start, max(out[-1].end, iv.end))
        else:
            out.append(iv)
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


def script_room(scene: Scene, occ: OccupancyGrid, rng: np.random.Generator, total_frames: int,
                take_seconds: tuple[float, float] = (30.0, 90.0), fps: float = 30.0) -> list[Take]:
    """Takes in ``scene`` adding up to at least ``total_frames`` frames; each take lasts about
    U(take_seconds) seconds (the last one is shortened to the remainder, at least 8 s)."""
    ctx = RoomContext.build(scene, occ, fps)
    coverage: dict[str, int] = {}
    takes: list[Take] = []
    done = 0
    while done < total_frames:
        n = int(rng.uniform(*take_seconds) * fps)
        rest = total_frames - done
        if rest < n + take_seconds[0] * fps:
            n = max(rest, int(min(8.0, take_seconds[0]) * fps))
        take = script_take(ctx, rng, n, coverage)
        takes.append(take)
        done += take.sequence.num_frames
    return takes
