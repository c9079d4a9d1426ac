"""Activities on seats: sitting on a chair, stool, sofa or bed, lying on a bed or sofa, and desk
work (sitting at the desk's chair, typing and using the mouse)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from trumans.contacts.rule import JOINT_RADIUS
from trumans.skeleton import SEAT, forward_kinematics
from . import hands, lying, posture
from .motion import Motion, yaw_of
from .moves import MAX_PENETRATION, approach, check_clean, walk_to, world_point
from .room import RoomContext
from .take import Skip, TakeState

__all__ = ["run_sit", "run_lie", "run_desk_work"]

def _rest_lift(rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, surface_z: float, joints: list[int]) -> float:
    """How far (m) a resting state must be raised so that the body surface of ``joints`` (joint
    height minus its contact radius) is not below ``surface_z``."""
    P, _ = forward_kinematics(rot[None], root[None], offsets)
    gap = P[0, joints, 2] - surface_z - JOINT_RADIUS[joints]
    return float(max(0.0, -gap.min()))




def _seat(obj, pose: np.ndarray, offsets: np.ndarray, rng: np.random.Generator,
          near: np.ndarray | None = None) -> tuple[np.ndarray, float, np.ndarray, posture.Stagger]:
    """World (seat point raised so the seated body rests on the surface, sit yaw, stand point, foot
    stagger): a random place of the seat, or the one nearest world xy ``near``; the sitting's foot
    stagger (``posture.draw_stagger``; none where the staggered foot cannot reach the floor)."""
    centers = [world_point(pose, c) for c in (obj.meta.get("seat_centers") or [obj.meta["seat_center"]])]
    if near is None:
        c = centers[rng.integers(len(centers))]
    else:
        c = min(centers, key=lambda p: float(np.linalg.norm(p[:2] - np.asarray(near)[:2])))
    yaw = yaw_of(pose) + float(obj.meta["sit_yaw"])
    stand = c[:2] + (world_point(pose, obj.meta["approach"]) - world_point(pose, obj.meta["seat_center"]))[:2]
    try:
        rot, root = posture.seated_state(offsets, c, yaw, stand)
        c = c + [0.0, 0.0, _rest_lift(rot, root, offsets, float(c[2]), list(SEAT))]
        posture.seated_state(offsets, c, yaw, stand)
    except ValueError as e:  # this actor's feet cannot reach the floor from this seat
        raise Skip(str(e)) from e
    stagger = posture.draw_stagger(rng)
    try:
        posture.seated_state(offsets, c, yaw, stand, stagger=stagger)
    except ValueError:  # the pushed-forward foot would not reach the floor from this (high) seat
        stagger = (0.0, 0.0)
    return c, yaw, stand, stagger


def _posture_change(ctx: RoomContext, st: TakeState, rng: np.random.Generator, fn, args: tuple, what: str,
                    stagger: posture.Stagger) -> Motion:
    """``fn(*args, rng, fps=..., arm_swing=..., stagger=...)`` (sit_down / stand_up) with the arms swinging
    forward for balance, or held back where they would hit something in front (a desk); Skip if still unclean."""
    m = fn(*args, rng, fps=ctx.fps, stagger=stagger)
    if ctx.worst_penetration(m, st.poses)[0] <= MAX_PENETRATION:
        return m
    return check_clean(ctx, st, fn(*args, rng, fps=ctx.fps, arm_swing=0.0, stagger=stagger), what)


def _shifting(ctx: RoomContext, st: TakeState, rng: np.random.Generator,
              idle: Callable[[np.random.Generator, float], Motion]) -> Motion:
    """A seated/lying idle ``idle(rng, shift)`` whose body shifts on the surface: the same idle
    (one seed) with the full shift, half of it, or none, the first that stays out of the furniture."""
    seed = int(rng.integers(2**31))
    for shift in (1.0, 0.5):
        m = idle(np.random.default_rng(seed), shift)
        if ctx.worst_penetration(m, st.poses)[0] <= MAX_PENETRATION:
            return m
    return idle(np.random.default_rng(seed), 0.0)


def _sit_on(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str,
            seated: Callable[[np.ndarray, float, np.ndarray, posture.Stagger], None] | None = None,
            near: np.ndarray | None = None) -> None:
    """Walk to the seat ``name``, sit down, sit (``seated(seat, yaw, stand, stagger)``, default an
    idle), stand up; one foot staggered from the sit-down to the stand-up."""
    obj = ctx.scene.objects[name]
    pose = st.poses.get(name, obj.pose)
    seat, yaw, stand, stagger = _seat(obj, pose, st.offsets, rng, near)
    m = walk_to(ctx, st, rng, stand, yaw)
    if m is not None:
        st.append(m)
    args = (st.offsets, seat, yaw, stand)
    st.append(_posture_change(ctx, st, rng, posture.sit_down, args, "sit_down", stagger))
    if seated is None:
        n = int(rng.uniform(2.0, 8.0) * ctx.fps)
        st.append(check_clean(ctx, st, _shifting(ctx, st, rng, lambda r, shift: posture.sit(
            st.offsets, seat, yaw, stand, n, r, fps=ctx.fps, shift=shift, stagger=stagger)), "sit"))
    else:
        seated(seat, yaw, stand, stagger)
    st.append(_posture_change(ctx, st, rng, posture.stand_up, args, "stand_up", stagger))


def run_sit(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Walk to a seat, sit down, sit a while, stand up."""
    _sit_on(ctx, st, rng, name)


def run_lie(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Walk to a bed or sofa, sit on its edge, lie down, lie a while, get up, stand up. The body
    lies along the surface (``lie_center``, ``lie_yaw``, ``lie_length`` meta) where
    ``lying.fit_lying`` puts it: most takes knees up (bent 95-120 deg, as people lie), else
    straight where the body fits, knees up on a short sofa; the seat place nearest the lying pelvis
    is used. The lying idle shifts the body on the surface, less where a full shift would go into
    the furniture."""
    obj = ctx.scene.objects[name]
    pose = st.poses.get(name, obj.pose)
    ly = yaw_of(pose) + float(obj.meta["lie_yaw"])
    prefer = lying.min_leg_reach(st.offsets) * rng.uniform(1.11, 1.38) if rng.random() < 0.75 else None
    try:
        shift, reach = lying.fit_lying(st.offsets, float(obj.meta["lie_length"]), prefer_reach=prefer)
    except ValueError as e:
        raise Skip(f"{name}: {e}") from e
    lc = world_point(pose, obj.meta["lie_center"]) + shift * np.array([np.cos(ly), np.sin(ly), 0.0])

    def lie_there(seat: np.ndarray, yaw: float, stand: np.ndarray, stagger: posture.Stagger) -> None:
        kw = dict(sit_yaw=yaw, stand_pos=stand, fps=ctx.fps, leg_reach=reach, stagger=stagger)
        st.append(check_clean(ctx, st, lying.lie_down(st.offsets, lc, ly, seat, rng, **kw), "lie_down"))
        n = int(rng.uniform(5.0, 12.0) * ctx.fps)
        st.append(check_clean(ctx, st, _shifting(ctx, st, rng, lambda r, shift: lying.lie(
            st.offsets, lc, ly, n, r, fps=ctx.fps, leg_reach=reach, shift=shift)), "lie"))
        st.append(check_clean(ctx, st, lying.get_up(st.offsets, lc, ly, seat, rng, **kw), "get_up"))

    _sit_on(ctx, st, rng, name, seated=lie_there, near=lc)


def run_desk_work(ctx: RoomContext, st: TakeState, rng: np.random.Generator, name: str) -> None:
    """Sit on the desk's chair, type on the keyboard and use the mouse, stand up."""
    kb = ctx.scene.objects[name]
    desk = ctx.scene.objects.get(str(kb.meta.get("support", "")))
    if desk is None:
        raise Skip(f"{name} stands on no desk")
    goal, _ = approach(desk, desk.pose)
    chairs = [(np.linalg.norm(approach(o, st.poses[n])[0] - goal), n) for n, o in ctx.scene.objects.items()
              if o.category == "chair"]
    chairs = [c for c in chairs if c[0] < 0.3]
    if not chairs:
        raise Skip(f"no chair at {desk.name}")
    chair = min(chairs)[1]
    mice = [n for n, o in ctx.scene.objects.items() if o.category == "mouse" and o.meta.get("support") == desk.name]

    def work(seat: np.ndarray, yaw: float, stand: np.ndarray, stagger: posture.Stagger) -> None:
        def base(kind: str) -> Motion:
            n = hands.nominal_frames(kind, rng, ctx.fps)
            return posture.sit(st.offsets, seat, yaw, stand, n, rng, fps=ctx.fps, shift=0.3,  # at the desk
                               stagger=stagger)

        order = ["type"] + (["use_mouse"] if mice else [])
        if len(order) == 2 and rng.random() < 0.5:
            order.reverse()
        for kind in order:
            try:
                if kind == "type":
                    m = hands.type_keyboard(base("type"), kb, st.poses[name], rng)
                    grasped = {hands.WRIST["left"]: name, hands.WRIST["right"]: name}
                else:
                    mouse = mice[0]
                    m = hands.use_mouse(base("use_mouse"), ctx.scene.objects[mouse], st.poses[mouse], rng)
                    grasped = {w: mouse for w in m.grasp}
            except hands.OutOfReach as e:
                raise Skip(f"{kind} at {desk.name}: {e}") from e
            st.append(check_clean(ctx, st, m, kind), grasped)

    _sit_on(ctx, st, rng, chair, seated=work)
