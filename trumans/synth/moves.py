"""The moves every activity is made of: walking to a goal on the room's walk maps, idling, the
standing base of a hand primitive, and the check that rejects a motion going into the scene."""
from __future__ import annotations

import numpy as np

from trumans.scenes.walkability import NoPathError, nearest_walkable, plan_path

from . import hands, locomotion
from .legs import wrap_angle
from .motion import Motion, yaw_of
from .room import RoomContext
from .take import Skip, TakeState

__all__ = ["MAX_WALK_PENETRATION", "MAX_PENETRATION", "world_point", "walk_to", "idle", "go_to",
           "check_clean", "stand_base", "approach", "grasped_by"]

MAX_WALK_PENETRATION = 0.015  # m, a planned walk that brushes furniture deeper than this is rejected
MAX_PENETRATION = 0.025  # m, an interaction deeper than this into the scene is rejected (activity skipped)


def world_point(pose: np.ndarray, p_local) -> np.ndarray:
    """World point (3,) of a point (3,) or floor point (2,) given in the frame of ``pose`` (4, 4)."""
    p = np.asarray(p_local, dtype=np.float64)
    if p.shape == (2,):
        p = np.array([p[0], p[1], 0.0])
    return pose[:3, :3] @ p + pose[:3, 3]


def walk_to(ctx: RoomContext, st: TakeState, rng: np.random.Generator, goal: np.ndarray, goal_yaw: float,
            base_pose: str = "stand") -> Motion | None:
    """A walk (or a turn in place) from the actor's position to pelvis xy ``goal`` facing
    ``goal_yaw``; None when already there. The path is planned on the walk map to the walkable
    cell nearest the goal, which is then appended as the final waypoint (approach points lie close
    to furniture). Maps with more clearance are tried first; a walk whose pelvis track leaves the
    check map (away from its two ends) is rejected. Raises Skip when no map gives a clean walk."""
    goal = np.asarray(goal, dtype=np.float64)[:2]
    if np.linalg.norm(goal - st.pos) < 0.08:
        if abs(float(wrap_angle(goal_yaw - st.yaw))) < np.radians(8):
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


def idle(ctx: RoomContext, st: TakeState, rng: np.random.Generator, lo: float = 0.5, hi: float = 2.5) -> Motion:
    return locomotion.stand(st.offsets, st.pos, st.yaw, int(rng.uniform(lo, hi) * ctx.fps), rng, fps=ctx.fps)


def check_clean(ctx: RoomContext, st: TakeState, m: Motion, what: str) -> Motion:
    """Raise Skip when motion ``m`` penetrates the scene deeper than MAX_PENETRATION."""
    depth, where = ctx.worst_penetration(m, st.poses)
    if depth > MAX_PENETRATION:
        raise Skip(f"{what} penetrates the scene by {100 * depth:.1f} cm ({where})")
    return m


def stand_base(ctx: RoomContext, st: TakeState, rng: np.random.Generator, kind: str) -> Motion:
    """Standing base motion of natural length for hand primitive ``kind``."""
    return locomotion.stand(st.offsets, st.pos, st.yaw, hands.nominal_frames(kind, rng, ctx.fps), rng, fps=ctx.fps)


def approach(obj, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """World pelvis xy and heading from which a person interacts with ``obj`` at ``pose``."""
    return world_point(pose, obj.meta["approach"])[:2], yaw_of(pose) + float(obj.meta["approach_yaw"])


def go_to(ctx: RoomContext, st: TakeState, rng: np.random.Generator, pos: np.ndarray, yaw: float) -> None:
    m = walk_to(ctx, st, rng, pos, yaw)
    if m is not None:
        st.append(m)


def grasped_by(m: Motion, name: str) -> dict[int, str]:
    return {w: name for w, g in m.grasp.items() if np.any(g)}
