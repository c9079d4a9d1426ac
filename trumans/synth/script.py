"""Per-room take scripting: a random sequence of activities chosen from what a room contains.

A *take* is one continuous performance of one actor in one room: idle -> walk (planned path to an
object's approach point) -> interact -> walk -> ... (``activities.ACTIVITIES``). Less performed
activities are preferred so that a room shows all it affords; an activity that cannot be performed
from where the actor is (``take.Skip``) is rolled back and recorded.
"""
from __future__ import annotations

import numpy as np

from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.scene import Scene

from . import hands
from .activities import ACTIVITIES, candidates
from .moves import idle
from .room import RoomContext
from .take import Skip, Take, TakeState, draw_actor

__all__ = ["script_take", "script_room"]


def script_take(ctx: RoomContext, rng: np.random.Generator, n_frames: int, coverage: dict[str, int]) -> Take:
    """One take of at least ``n_frames`` frames (it ends after the activity that crosses it).

    ``coverage`` counts how often each activity has been performed in the room (updated): less
    performed activities are preferred, so a room shows all it affords."""
    offsets = draw_actor(rng)
    wm = next((w for w in ctx.plans if w.walkable.any()), None)
    if wm is None:
        raise ValueError(f"room {ctx.scene.name!r} has no walkable floor")
    cells = np.argwhere(wm.walkable)
    pos = wm.centers(cells[rng.integers(len(cells))])
    st = TakeState(offsets=offsets, speed=float(rng.uniform(0.75, 1.15)), pos=pos, yaw=float(rng.uniform(-np.pi, np.pi)),
                   poses={n: o.pose.copy() for n, o in ctx.scene.objects.items() if o.dynamic})
    st.append(idle(ctx, st, rng, 0.5, 2.0))
    cands = candidates(ctx.scene)
    failures = 0
    done: dict[str, int] = {}
    skipped: dict[str, list[str]] = {}
    while st.frames < n_frames and failures < 30:
        counts = np.array([coverage.get(a, 0) for a, _ in cands], dtype=np.float64)
        w = np.exp(-1.5 * (counts - counts.min()))
        w[[i for i, (a, _) in enumerate(cands) if a == "wander"]] *= 0.3
        act, obj = cands[rng.choice(len(cands), p=w / w.sum())]
        snapshot = st.snapshot()
        try:
            ACTIVITIES[act].run(ctx, st, rng, obj)
            coverage[act] = coverage.get(act, 0) + 1
            done[act] = done.get(act, 0) + 1
        except (Skip, hands.OutOfReach) as e:  # OutOfReach: the hand cannot reach from where the body is
            skipped.setdefault(act, []).append(f"{obj}: {e}")
            st.restore(snapshot)
            failures += 1
            coverage[act] = coverage.get(act, 0) + 1  # do not insist on an impossible activity
    take = st.finish(ctx)
    take.done, take.skipped = done, skipped
    return take


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
