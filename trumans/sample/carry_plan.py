"""Object steps of a plan (pick_up / put_down / open / close): checks and hand goals.

``validate_carry`` rejects, before any sampling, a plan that picks up something that is not a free
(6-DoF) object, puts down an object it does not hold, picks up a second object with the hand that
holds one, or puts an object down on something that is not a surface. ``ObjectState`` follows
where every object is while the plan is compiled, so that ``object_step_goals`` gives the hand
goals of each step: the grasp point of the object where it lies now (pick_up), the grasp point of
the object placed on the target surface / point (put_down), and for open / close the handle first
where it is and then where it is at the end of the motion (``OPEN_FRACTION`` of the door's
``max_angle`` or the drawer's ``max_travel``; 0 when closing).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trumans.track.objects import rotation_about_axis

__all__ = ["OPEN_FRACTION", "GRASP_SPAN", "STAND_M", "ObjectState", "StepGoals", "validate_carry", "object_step_goals",
           "articulated_pose", "surface_point", "planned_object_poses"]

OPEN_FRACTION = 0.7  # an "open" step opens a door / drawer to this fraction of its range
GRASP_SPAN = 0.4  # fraction of an open / close step spent reaching the handle (the rest moves it)
EDGE_M = 0.12  # a put-down point on a surface lies this far inside its edge nearest the person
STAND_M = 0.45  # pelvis to the hand's work point, horizontal m (training data: 0.35-0.65 m from a handle)


@dataclass
class ObjectState:
    """While compiling: pose (4, 4) world of every object moved so far, the opening fraction of
    doors / drawers, and what each hand holds."""

    poses: dict[str, np.ndarray] = field(default_factory=dict)
    opening: dict[str, float] = field(default_factory=dict)
    held: dict[str, str] = field(default_factory=dict)  # object name -> hand ("left" / "right")


@dataclass(frozen=True)
class StepGoals:
    """Hand goals of one object step: ``points`` (world m) reached at the end of consecutive
    sub-phases whose progress spans are ``spans``; ``stand``: (2,) floor point where the pelvis
    stands (``STAND_M`` from the hand's work point, towards the object's approach point or the
    person), before any walkability check."""

    points: tuple[np.ndarray, ...]
    spans: tuple[tuple[float, float], ...]
    stand: np.ndarray
    after: np.ndarray | None = None  # (4, 4) world pose of the object when the step is done (None: held)
    path: np.ndarray | None = None  # (M, 3) world m: the handle's way from points[0] to points[1] (open / close)


def _stand(work: np.ndarray, towards_obj, pos: np.ndarray) -> np.ndarray:
    """(2,) STAND_M from ``work`` (3,) towards the approach point of ``towards_obj`` (or ``pos``)."""
    if towards_obj is not None and "approach" in towards_obj.meta:
        a = np.zeros(3)
        a[:2] = towards_obj.meta["approach"]
        to = (towards_obj.pose[:3, :3] @ a + towards_obj.pose[:3, 3])[:2]
    else:
        to = np.asarray(pos, np.float64)
    d = to - work[:2]
    return work[:2] + STAND_M * d / max(float(np.linalg.norm(d)), 1e-6)


def surface_point(obj, margin: float = EDGE_M) -> np.ndarray:
    """(3,) world point on a surface object's top (meta 'surface_center', 'surface_size'): the
    point ``margin`` m inside the edge nearest its approach point (within reach of a person
    standing there), or the centre when the meta has no size / approach."""
    c = np.asarray(obj.meta["surface_center"], np.float64).copy()
    if "surface_size" in obj.meta and "approach" in obj.meta:
        half = np.maximum(0.5 * np.asarray(obj.meta["surface_size"], np.float64) - margin, 0.0)
        c[:2] += np.clip(np.asarray(obj.meta["approach"], np.float64) - c[:2], -half, half)
    return obj.pose[:3, :3] @ c + obj.pose[:3, 3]


def articulated_pose(obj, fraction: float) -> np.ndarray:
    """(4, 4) world pose of a door (hinge) / drawer (slide) opened to ``fraction`` of its range
    (door: ``open_sign * max_angle``; drawer: ``max_travel`` along its axis)."""
    R, t = obj.pose[:3, :3], obj.pose[:3, 3]
    if obj.dof == "hinge":
        angle = fraction * float(obj.meta.get("open_sign", 1.0)) * float(obj.meta.get("max_angle", np.pi / 2))
        M = rotation_about_axis(np.array([angle]), R @ obj.axis, R @ obj.hinge_point + t)[0]
    else:
        M = np.eye(4)
        M[:3, 3] = fraction * float(obj.meta.get("max_travel", 0.3)) * (R @ obj.axis)
    return M @ obj.pose


def _local(obj, key: str) -> np.ndarray:
    return np.asarray(obj.meta.get(key) or obj.meta.get("handle") or [0.0, 0.0, 0.0], np.float64)


def validate_carry(plan, scene) -> None:
    """Raise ValueError naming the step when the plan's object steps cannot be done (module doc)."""
    held: dict[str, str] = {}
    for i, s in enumerate(plan.steps):
        where = f"plan step {i + 1} ({s.kind})"
        if s.kind not in ("pick_up", "put_down", "open", "close") or s.object not in scene.objects:
            continue  # unknown names are reported by validate_plan
        obj = scene.objects[s.object]
        if s.kind == "pick_up":
            if obj.dof != "free":
                raise ValueError(f"{where}: {s.object!r} is a {obj.category} (dof {obj.dof}) that cannot be picked "
                                 f"up; pick up a free object such as "
                                 f"{', '.join(sorted(n for n, o in scene.objects.items() if o.dof == 'free')) or '(none here)'}")
            if s.object in held:
                raise ValueError(f"{where}: {s.object!r} is already held; put it down first")
            if s.hand in held.values():
                other = next(n for n, h in held.items() if h == s.hand)
                raise ValueError(f"{where}: the {s.hand} hand already holds {other!r}; put it down first")
            held[s.object] = s.hand
        elif s.kind == "put_down":
            if s.object not in held:
                raise ValueError(f"{where}: {s.object!r} is not held; add a pick_up step for it before")
            del held[s.object]
            if isinstance(s.target, str) and s.target in scene.objects and \
                    "surface_center" not in scene.objects[s.target].meta:
                raise ValueError(f"{where}: {s.target!r} is a {scene.objects[s.target].category} without a surface "
                                 f"(meta 'surface_center'); put it on a table, desk or cabinet or give a point [x, y, z]")
        elif obj.dof not in ("hinge", "slide") or obj.axis is None:
            raise ValueError(f"{where}: {s.object!r} (dof {obj.dof}) is not a door or drawer that opens")


def object_step_goals(scene, step, state: ObjectState, pos: np.ndarray) -> StepGoals:
    """Hand goals of an object step from the person standing at ``pos`` (2,); updates ``state``."""
    obj = scene.objects[step.object]
    pose = state.poses.get(obj.name, obj.pose)
    if step.kind == "pick_up":
        grasp = pose[:3, :3] @ _local(obj, "grasp_point") + pose[:3, 3]
        support = scene.objects.get(obj.meta.get("support", ""))
        state.held[obj.name] = step.hand
        return StepGoals((grasp,), ((0.0, 1.0),), _stand(grasp, support if obj.name not in state.poses else None, pos))
    if step.kind == "put_down":
        state.held.pop(obj.name, None)
        place = pose.copy()  # default: back where it was
        stand = scene.objects.get(obj.meta.get("support", "")) if obj.name not in state.poses else None
        if isinstance(step.target, str):
            place[:3, 3] = surface_point(scene.objects[step.target])
            stand = scene.objects[step.target]
        elif step.target is not None:
            place[:3, 3] = np.asarray(step.target, np.float64)
            stand = None
        state.poses[obj.name] = place
        grasp = place[:3, :3] @ _local(obj, "grasp_point") + place[:3, 3]
        return StepGoals((grasp,), ((0.0, 1.0),), _stand(grasp, stand, pos), place)
    # open / close: reach the handle where it is, then move it to where it ends
    now = state.opening.get(obj.name, 0.0)
    end = OPEN_FRACTION if step.kind == "open" else 0.0
    state.opening[obj.name] = end
    handle = _local(obj, "handle")
    a, b = articulated_pose(obj, now), articulated_pose(obj, end)
    p0, p1 = a[:3, :3] @ handle + a[:3, 3], b[:3, :3] @ handle + b[:3, 3]
    poses = [articulated_pose(obj, f) for f in np.linspace(now, end, 17)]  # the handle's way (reach cleanup)
    path = np.stack([P[:3, :3] @ handle + P[:3, 3] for P in poses])
    stand = obj if "approach" in obj.meta else scene.objects.get(obj.meta.get("parent", ""))
    return StepGoals((p0, p1), ((0.0, GRASP_SPAN), (GRASP_SPAN, 1.0)), _stand(0.5 * (p0 + p1), stand, pos), b, path)


_AWAY = np.diag([1.0, 1.0, 1.0, 1.0])
_AWAY[2, 3] = -100.0  # a held object is left out of the scene grids (it moves with the body)


def planned_object_poses(controllers: list, grids) -> dict[str, np.ndarray] | None:
    """name -> (B, 4, 4) poses of the objects moved by the object steps each controller has
    finished (``Phase.info['after']``; a picked-up object is taken out), for the scene grids of the
    next episode (``EpisodeSampler.episode(object_poses=...)``); None when nothing has moved yet."""
    if grids is None or not getattr(grids, "points", None):
        return None
    per = []
    for c in controllers:
        moved: dict[str, np.ndarray] = {}
        for p in c.phases[:c.index]:
            if "after" in p.info and p.info["object"] in grids.points:
                after = p.info["after"]
                moved[p.info["object"]] = _AWAY if after is None else after
        per.append(moved)
    names = sorted({n for m in per for n in m})
    if not names:
        return None
    return {n: np.stack([m.get(n, grids.scene_pose[n]) for m in per]) for n in names}
