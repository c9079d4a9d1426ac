"""Activities with furniture: open and close a door or a drawer, push / pull a chair, stool or table."""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import hands
from .motion import Motion
from .moves import check_clean, go_to, grasped_by, idle, stand_base
from .room import RoomContext
from .take import Skip, TakeState

__all__ = ["MIN_DOOR_ANGLE", "MIN_DRAWER_TRAVEL", "run_door", "run_drawer", "run_push_pull", "pushable"]

MIN_DOOR_ANGLE = 0.8  # rad, a door opened less than this is no use: skip the activity
MIN_DRAWER_TRAVEL = 0.12  # m, the same for a drawer


def _stance(plan, st: TakeState, obj, closed: np.ndarray, least: float, unit: str):
    """``plan(offsets, obj, closed)`` (door_stance / drawer_stance); Skip when no stance works or
    the opening reachable from it is under ``least`` (rad / m: ``unit``)."""
    try:
        stance = plan(st.offsets, obj, closed)
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    if stance.reach < least:
        raise Skip(f"{obj.name} opens only {stance.reach:.2f} {unit} from its stance")
    return stance


def _open_wait_close(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str, stance,
                     open_it: Callable[[], Motion], close_it: Callable[[], Motion], kind: str) -> None:
    """Walk to the stance, open ``name`` (``open_it()``), wait a moment, close it (``close_it()``);
    the motions are labelled open_<kind> / close_<kind>."""
    go_to(ctx, st, rng, stance.pos, stance.yaw)
    try:
        m = open_it()
        st.append(check_clean(ctx, st, m, f"open_{kind} {name}"), grasped_by(m, name))
        st.append(idle(ctx, st, rng, 0.3, 1.5))
        m = close_it()
    except hands.OutOfReach as e:
        raise Skip(str(e)) from e
    st.append(check_clean(ctx, st, m, f"close_{kind} {name}"), grasped_by(m, name))


def run_door(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Walk to the door, pull it open stepping back, wait, push it closed stepping forwards."""
    door = ctx.scene.objects[name]
    closed = st.poses[name].copy()
    stance = _stance(hands.door_stance, st, door, closed, MIN_DOOR_ANGLE, "rad")
    angle = float(min(stance.reach, rng.uniform(0.6, 1.0) * float(door.meta["max_angle"])))  # rad
    _open_wait_close(ctx, st, rng, name, stance,
                     lambda: hands.open_door(st.offsets, door, closed, angle, rng, stance, fps=ctx.fps),
                     lambda: hands.close_door(st.offsets, door, closed, angle, rng, stance, fps=ctx.fps), "door")


def run_drawer(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Walk to a cabinet drawer, pull it out, wait, push it closed."""
    dr = ctx.scene.objects[name]
    closed = st.poses[name].copy()
    stance = _stance(hands.drawer_stance, st, dr, closed, MIN_DRAWER_TRAVEL, "m")
    travel = float(min(stance.reach, rng.uniform(0.5, 1.0) * float(dr.meta["max_travel"])))
    _open_wait_close(ctx, st, rng, name, stance,
                     lambda: hands.open_drawer(stand_base(ctx, st, rng, "open_drawer"), dr, closed, travel, rng,
                                               side=stance.side),
                     lambda: hands.close_drawer(stand_base(ctx, st, rng, "close_drawer"), dr, closed, travel, rng,
                                                side=stance.side), "drawer")


def _object_clear(ctx: RoomContext, name: str, pose: np.ndarray) -> bool:
    """True when object ``name`` placed at ``pose`` intersects no static mesh / static object."""
    if ctx.contacts.static is None:
        return True
    v = ctx.scene.objects[name].mesh.vertices
    pts = v @ pose[:3, :3].T + pose[:3, 3]
    r = ctx.contacts.static.query(pts[pts[:, 2] > 0.01][None])
    return not bool(r.inside.any())


def run_push_pull(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Push a chair / stool / table a few decimetres along the floor, then pull it back."""
    obj = ctx.scene.objects[name]
    if not obj.dynamic or obj.dof != "slide":
        raise Skip(f"{name} does not slide")
    pose = st.poses[name].copy()
    d = float(rng.uniform(0.2, 0.4))
    try:
        hands.push_handles(obj)
    except ValueError as e:  # the object has no place to put the hands (e.g. a stool)
        raise Skip(f"cannot push {name}: {e}") from e
    try:
        pos, yaw = hands.push_stance(st.offsets, obj, pose)
        first = hands.push(st.offsets, obj, pose, d, rng, fps=ctx.fps)
        order = ("push", "pull")
        if not _slide_clear(ctx, name, first):  # e.g. a chair tucked under a desk: pull it out first
            first = hands.pull(st.offsets, obj, pose, d, rng, fps=ctx.fps)
            order = ("pull", "push")
            if not _slide_clear(ctx, name, first):
                raise Skip(f"moving {name} {d:.2f} m either way runs into the room")
    except hands.OutOfReach as e:
        raise Skip(f"cannot push {name}: {e}") from e
    go_to(ctx, st, rng, pos, yaw)
    st.append(check_clean(ctx, st, first, f"{order[0]} {name}"), grasped_by(first, name))
    moved = first.objects[name][-1]
    try:
        if order[1] == "pull":
            back = hands.pull(st.offsets, obj, moved, d, rng, fps=ctx.fps)
        else:
            back = hands.push(st.offsets, obj, moved, d, rng, fps=ctx.fps)
    except hands.OutOfReach as e:
        raise Skip(f"cannot {order[1]} {name}: {e}") from e
    st.append(check_clean(ctx, st, back, f"{order[1]} {name}"), grasped_by(back, name))


def _slide_clear(ctx: RoomContext, name: str, m: Motion) -> bool:
    """The object moved by push/pull motion ``m`` ends clear of the room and the body stays on
    walkable floor."""
    return _object_clear(ctx, name, m.objects[name][-1]) and bool(ctx.check.query(m.root[:, :2]).all())


def pushable(obj) -> bool:
    """A floor-sliding object with places for the hands (``hands.push_handles``)."""
    if not (obj.dynamic and obj.dof == "slide" and obj.axis is None):
        return False
    try:
        hands.push_handles(obj)
    except ValueError:
        return False
    return True
