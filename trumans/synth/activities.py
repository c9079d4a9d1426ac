"""The activity registry: each activity is a name, the object categories it applies to (none: it
needs no object) and ``run(ctx, state, rng, object_name)``, which appends its motions to the take
state or raises ``Skip`` when it cannot be performed from there."""
from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from trumans.scenes.scene import Scene

from . import activity_furniture as furniture
from . import activity_objects as objects
from . import activity_seats as seats
from .moves import idle, walk_to
from .room import RoomContext
from .take import TakeState

__all__ = ["Activity", "ACTIVITIES", "candidates"]


class Activity(NamedTuple):
    """categories: object categories the activity applies to (empty: no object); run(ctx, state, rng, name)."""

    categories: tuple[str, ...]
    run: Callable[[RoomContext, TakeState, np.random.Generator, str], None]


def run_wander(ctx: RoomContext, st: TakeState, rng: np.random.Generator, _: str) -> None:
    """Walk to a random walkable floor point and stand there a moment."""
    cells = np.argwhere(ctx.plans[0].walkable)
    for _try in range(10):
        goal = ctx.plans[0].centers(cells[rng.integers(len(cells))])
        if np.linalg.norm(goal - st.pos) > 1.0:
            break
    m = walk_to(ctx, st, rng, goal, float(rng.uniform(-np.pi, np.pi)))
    if m is not None:
        st.append(m)
    st.append(idle(ctx, st, rng))


ACTIVITIES: dict[str, Activity] = {  # the order is part of the data: candidates are drawn in this order
    "wander": Activity((), run_wander),
    "sit": Activity(("chair", "stool", "sofa", "bed"), seats.run_sit),
    "lie": Activity(("bed", "sofa"), seats.run_lie),
    "pick_place": Activity(objects.SMALL, objects.run_pick_place),
    "drink": Activity(("bottle", "cup"), objects.run_drink),
    "phone_call": Activity(("phone",), objects.run_phone_call),
    "desk_work": Activity(("keyboard",), seats.run_desk_work),
    "door": Activity(("door",), furniture.run_door),
    "drawer": Activity(("drawer",), furniture.run_drawer),
    "push_pull": Activity(("chair", "stool", "table"), furniture.run_push_pull),
}


def candidates(scene: Scene) -> list[tuple[str, str]]:
    """(activity, object) pairs this room supports."""
    out = []
    for act, (cats, _) in ACTIVITIES.items():
        if not cats:
            out.append((act, ""))
            continue
        out += [(act, n) for n, o in scene.objects.items() if o.category in cats and
                (act != "push_pull" or furniture.pushable(o))]
    return out
