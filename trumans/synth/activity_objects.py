"""Activities with small objects: pick one up and put it down elsewhere, drink, make a phone call."""
from __future__ import annotations

import numpy as np

from . import hands
from .motion import yaw_of
from .moves import approach, check_clean, stand_base, walk_to, world_point
from .room import RoomContext
from .take import Skip, TakeState

__all__ = ["SMALL", "SURFACES", "run_pick_place", "run_drink", "run_phone_call"]

SMALL = ("bottle", "cup", "phone", "book", "pen", "vase")
SURFACES = ("table", "desk", "cabinet")


def _approach_point(ctx: RoomContext, st: TakeState, name: str, target: np.ndarray) -> tuple[np.ndarray, float]:
    """Where to stand to handle something at world ``target`` on object ``name``'s support: the
    support's approach line (parallel to its front edge) at the point in front of the target."""
    obj = ctx.scene.objects[name]
    sup = ctx.scene.objects.get(str(obj.meta.get("support", ""))) if obj.category in SMALL + (
        "keyboard", "mouse", "laptop") else obj
    if sup is None or "surface_size" not in sup.meta:
        return approach(obj, st.poses.get(name, obj.pose))
    pose = st.poses.get(sup.name, sup.pose)
    # Surfaces face +x (trumans.scenes.furniture): stand 0.28 m in front of the front edge, facing -x.
    a = world_point(pose, [0.5 * float(sup.meta["surface_size"][0]) + 0.28, 0.0])[:2]
    yaw = yaw_of(pose) + np.pi
    along = pose[:2, 1]  # the support's local y axis (its front edge direction) in the world
    half = 0.5 * float(sup.meta["surface_size"][1]) - 0.15
    u = float(np.clip((target[:2] - a) @ along, -max(half, 0.0), max(half, 0.0)))
    return a + u * along, yaw


def _sides(ctx: RoomContext, st: TakeState, target: np.ndarray, rng: np.random.Generator) -> list[str]:
    """Hands to try, the one on the target's side of the body first (random when centred)."""
    rel = (target[:2] - st.pos) @ np.array([-np.sin(st.yaw), np.cos(st.yaw)])
    first = ("left" if rel > 0 else "right") if abs(rel) > 0.05 else ("left", "right")[rng.integers(2)]
    return [first, "right" if first == "left" else "left"]


def _grab(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str):
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
            mp, hold = hands.pick_up(stand_base(ctx, st, rng, "pick_up"), obj, pose, side, rng)
        except hands.OutOfReach as e:
            last = e
            continue
        st.append(check_clean(ctx, st, mp, f"pick_up {name}"), {hands.WRIST[side]: name})
        return hold
    raise Skip(f"cannot reach {name}: {last}")


def _release(ctx: RoomContext, st: TakeState, rng: np.random.Generator, hold, target: np.ndarray) -> None:
    try:
        m = hands.put_down(stand_base(ctx, st, rng, "put_down"), hold, target, rng)
    except hands.OutOfReach as e:
        raise Skip(f"cannot put {hold.name} down: {e}") from e
    st.append(check_clean(ctx, st, m, f"put_down {hold.name}"), {hands.WRIST[hold.side]: hold.name})


def _free_spot(ctx: RoomContext, st: TakeState, rng: np.random.Generator, support: str,
               moving: str) -> np.ndarray | None:
    """A world pose on ``support``'s top near its front edge, >= 12 cm from other small objects."""
    sup = ctx.scene.objects[support]
    sx, sy = sup.meta["surface_size"]
    h = float(sup.meta["surface_height"])
    others = [p[:3, 3] for n, p in st.poses.items() if n != moving and ctx.scene.objects[n].category in
              SMALL + ("keyboard", "mouse", "laptop")]
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


def run_pick_place(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Pick a small object up, carry it to a (possibly other) table / desk / cabinet, put it down."""
    supports = [n for n, o in ctx.scene.objects.items() if o.category in SURFACES]
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
        st.append(check_clean(ctx, st, hands.carry(m, hold), f"carry {name}"), {hands.WRIST[hold.side]: name})
    _release(ctx, st, rng, hold, target)


def _use_and_put_back(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str, kind: str, use) -> None:
    """Pick object ``name`` up, use it (``use(base, hold, obj, rng)``, primitive ``kind``), put it back."""
    where = st.poses[name].copy()
    hold = _grab(ctx, st, rng, name)
    m = use(stand_base(ctx, st, rng, kind), hold, ctx.scene.objects[name], rng)
    st.append(check_clean(ctx, st, m, f"{kind} {name}"), {hands.WRIST[hold.side]: name})
    _release(ctx, st, rng, hold, where)


def run_drink(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Pick up a bottle or cup, drink, put it back where it was."""
    _use_and_put_back(ctx, st, rng, name, "drink", hands.drink)


def run_phone_call(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Pick up a phone, make a call, put it back where it was."""
    _use_and_put_back(ctx, st, rng, name, "phone_call", hands.phone_call)
