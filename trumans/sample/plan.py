"""Plans: what the person does, in order (the sampling issue, "Plans").

A plan is a start (floor point ``(x, y)`` m and heading rad, both optional) and a list of steps:

- ``goto``     ``to = [x, y]``                       walk there along an A* path
- ``sit_on``   ``object = NAME``, ``seconds``        walk to the seat, sit down, stay seated
- ``lie_on``   ``object = NAME``, ``seconds``        walk to the bed / sofa, lie down, stay lying
- ``stand_up`` / ``get_up``                          leave the seat / bed (added automatically
                                                     before the next movement when omitted)
- ``reach``    ``target = NAME or [x, y, z]``, ``hand = left|right``
- ``act``      ``action = NAME`` (drink, phone_call, type, ...), ``seconds``
- ``open`` / ``close`` ``object = NAME`` (a door or drawer)
- ``pick_up`` ``object = NAME``                     a free (6-DoF) object
- ``put_down`` ``object = NAME``, ``target = SURFACE or [x, y, z]`` (optional: where it goes; default
  back where it was picked up)

Plans are read from JSON or TOML (``{"start": [x, y], "heading": h, "steps": [{"do": "goto",
"to": [1, 2]}, ...]}``) or built from command-line flags (``trumans.sample.cli``). ``validate_plan``
checks every name against the scene and the model's vocabulary, so a bad plan fails before any
sampling.
"""
from __future__ import annotations

import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from trumans.input_files import parse_json, parse_toml
from trumans.sample.carry_plan import validate_carry

__all__ = ["Step", "Plan", "STEP_KINDS", "load_plan", "plan_from_dict", "validate_plan", "far_point", "GOAL_MARGIN_M"]

StepKind = Literal["goto", "sit_on", "lie_on", "stand_up", "get_up", "reach", "act", "open", "close",
                   "pick_up", "put_down"]
MAX_REACH_HEIGHT = 2.4  # m above the floor: what a standing person can reach
# m a chosen walking goal lies inside the walkable floor (beyond the walk map's own 0.25 m body
# radius): the network overshoots a goal by 10-40 cm, and a goal on the map's edge put that into the wall
GOAL_MARGIN_M = 0.3
STEP_KINDS: tuple[str, ...] = ("goto", "sit_on", "lie_on", "stand_up", "get_up", "reach", "act", "open", "close",
                               "pick_up", "put_down")
_FIELDS: dict[str, set[str]] = {
    "goto": {"to"}, "sit_on": {"object", "seconds"}, "lie_on": {"object", "seconds"}, "stand_up": set(),
    "get_up": set(), "reach": {"target", "hand"}, "act": {"action", "seconds"}, "open": {"object"},
    "close": {"object"}, "pick_up": {"object"}, "put_down": {"object", "target"},
}
_REQUIRED: dict[str, set[str]] = {
    "goto": {"to"}, "sit_on": {"object"}, "lie_on": {"object"}, "reach": {"target"}, "act": {"action"},
    "open": {"object"}, "close": {"object"}, "pick_up": {"object"}, "put_down": {"object"},
}


@dataclass(frozen=True)
class Step:
    """One plan step. ``to``: (2,) world xy m; ``target``: object name or (3,) world point m;
    ``seconds``: how long the posture / action lasts (None = the model's typical duration)."""

    kind: StepKind
    to: tuple[float, float] | None = None
    object: str | None = None
    target: str | tuple[float, float, float] | None = None
    hand: Literal["left", "right"] = "right"
    action: str | None = None
    seconds: float | None = None


@dataclass(frozen=True)
class Plan:
    """start: (2,) world xy m or None (a walkable point near the room centre); heading: rad or None."""

    steps: tuple[Step, ...]
    start: tuple[float, float] | None = None
    heading: float | None = None
    name: str = "plan"
    meta: dict = field(default_factory=dict)


def _finite(values, what: str, n: int) -> tuple[float, ...]:
    try:
        arr = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be {n} numbers, got {values!r}") from None
    if arr.shape != (n,) or not np.isfinite(arr).all():
        raise ValueError(f"{what} must be {n} finite numbers, got {values!r}")
    return tuple(float(v) for v in arr)


def _step_from_dict(i: int, d: dict) -> Step:
    where = f"plan step {i + 1}"
    if not isinstance(d, dict):
        raise ValueError(f"{where} must be a table/object like {{\"do\": \"goto\", \"to\": [1, 2]}}, got {d!r}")
    d = dict(d)
    kind = d.pop("do", None)
    if kind not in STEP_KINDS:
        raise ValueError(f"{where}: unknown step {kind!r}; choose one of {', '.join(STEP_KINDS)} (key \"do\")")
    unknown = set(d) - _FIELDS[kind]
    if unknown:
        raise ValueError(f"{where} ({kind}): unknown keys {sorted(unknown)}; allowed: {sorted(_FIELDS[kind]) or 'none'}")
    missing = _REQUIRED.get(kind, set()) - set(d)
    if missing:
        raise ValueError(f"{where} ({kind}): missing {sorted(missing)}")
    kw: dict = {"kind": kind}
    if "to" in d:
        kw["to"] = _finite(d["to"], f"{where}: to", 2)
    if "object" in d:
        if not isinstance(d["object"], str) or not d["object"]:
            raise ValueError(f"{where}: object must be an object name, got {d['object']!r}")
        kw["object"] = d["object"]
    if "target" in d:
        kw["target"] = d["target"] if isinstance(d["target"], str) else _finite(d["target"], f"{where}: target", 3)
    if "hand" in d:
        if d["hand"] not in ("left", "right"):
            raise ValueError(f"{where}: hand must be 'left' or 'right', got {d['hand']!r}")
        kw["hand"] = d["hand"]
    if "action" in d:
        if not isinstance(d["action"], str):
            raise ValueError(f"{where}: action must be an action name, got {d['action']!r}")
        kw["action"] = d["action"]
    if "seconds" in d:
        s = d["seconds"]
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not math.isfinite(s) or not 0 < s <= 600:
            raise ValueError(f"{where}: seconds must be a number in (0, 600], got {s!r}")
        kw["seconds"] = float(s)
    return Step(**kw)


def plan_from_dict(d: dict, name: str = "plan") -> Plan:
    """A plan from its JSON/TOML form (see module doc); unknown keys are errors."""
    if not isinstance(d, dict):
        raise ValueError(f"a plan must be an object with 'steps', got {type(d).__name__}")
    unknown = set(d) - {"start", "heading", "steps", "name"}
    if unknown:
        raise ValueError(f"plan: unknown keys {sorted(unknown)}; allowed: start, heading, steps, name")
    steps = d.get("steps")
    if not isinstance(steps, list) or not steps:
        raise ValueError("plan: 'steps' must be a non-empty list, e.g. [{\"do\": \"goto\", \"to\": [1.0, 2.0]}]")
    start = _finite(d["start"], "plan: start", 2) if d.get("start") is not None else None
    heading = _finite([d["heading"]], "plan: heading", 1)[0] if d.get("heading") is not None else None
    return Plan(tuple(_step_from_dict(i, s) for i, s in enumerate(steps)), start, heading, str(d.get("name", name)))


def load_plan(path: str | Path) -> Plan:
    """Read a plan from a ``.json`` or ``.toml`` file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"plan file {path} does not exist; write one (see `trumans sample --help`) or "
                                f"give the steps as flags (--goto X,Y --sit-on NAME ...)")
    text = path.read_text()
    try:
        fix = "a plan is a flat list of steps (see docs/generate.md)"
        if path.suffix.lower() == ".toml":
            d = parse_toml(text, f"plan file {path}", fix)
        elif path.suffix.lower() == ".json":
            d = parse_json(text, f"plan file {path}", fix)
        else:
            raise ValueError(f"plan file {path} must end in .json or .toml")
    except (json.JSONDecodeError, tomllib.TOMLDecodeError) as e:
        raise ValueError(f"plan file {path} is not valid {path.suffix[1:].upper()}: {e}") from None
    return plan_from_dict(d, name=path.stem)


def far_point(wm, start: np.ndarray, within: float = 3.0, margin: float = GOAL_MARGIN_M) -> np.ndarray:
    """(2,) world xy m: the walkable cell farthest from ``start`` (2,) within ``within`` m, among the
    cells of start's walkable region at least ``margin`` m inside the walkable floor (the distance to
    the nearest cell that is not walkable); where none is that far inside, among the farthest inside.
    ``wm``: the scene's ``trumans.scenes.walkability.WalkMap``. Raises ValueError off the walkable floor."""
    from scipy import ndimage

    start = np.asarray(start, dtype=np.float64)
    if not wm.query(start[None])[0]:
        raise ValueError(f"start {np.round(start, 2).tolist()} is not on walkable floor")
    label, _ = ndimage.label(wm.walkable)
    i, j = wm.index(start)
    region = label == label[i, j]
    inside = ndimage.distance_transform_edt(wm.walkable) * wm.cell  # m to the nearest non-walkable cell
    idx = np.argwhere(region)
    pts, depth = wm.centers(idx), inside[idx[:, 0], idx[:, 1]]
    ok = depth >= min(margin, depth.max())
    d = np.linalg.norm(pts - start, axis=1)
    score = np.where(ok & (d < within), d, -1.0)
    return pts[int(np.argmax(score))]


# which object categories each step may name
_CATEGORIES: dict[str, tuple[str, ...]] = {
    "sit_on": ("chair", "stool", "sofa", "bed"),
    "lie_on": ("bed", "sofa"),
    "open": ("door", "drawer"), "close": ("door", "drawer"),
}


def validate_plan(plan: Plan, scene, vocabulary: list[str]) -> None:
    """Check object names / categories against ``scene`` and actions against ``vocabulary``.

    Raises ValueError naming the step, the problem and the choices; reachability is checked when
    the plan is compiled (``trumans.sample.controller.compile_plan``)."""
    vocab = set(vocabulary)
    for i, s in enumerate(plan.steps):
        where = f"plan step {i + 1} ({s.kind})"
        names = [s.object] if s.object else []
        if isinstance(s.target, str):
            names.append(s.target)
        for n in names:
            if n not in scene.objects:
                raise ValueError(f"{where}: scene {scene.name!r} has no object {n!r}; it has "
                                 f"{', '.join(sorted(scene.objects)) or 'no objects'}")
            cats = _CATEGORIES.get(s.kind)
            if cats and scene.objects[n].category not in cats:
                raise ValueError(f"{where}: {n!r} is a {scene.objects[n].category}; {s.kind} needs one of {cats}")
            meta = scene.objects[n].meta
            if s.kind == "sit_on" and "seat_center" not in meta:
                raise ValueError(f"{where}: {n!r} has no seat (meta 'seat_center'); choose a chair, stool, sofa or bed")
            if s.kind == "lie_on" and "lie_center" not in meta:
                raise ValueError(f"{where}: {n!r} has no lying surface (meta 'lie_center')")
        if s.kind == "reach" and not isinstance(s.target, str) and s.target is not None:
            z = float(s.target[2])
            if not 0.0 <= z <= MAX_REACH_HEIGHT:
                raise ValueError(f"{where}: target height {z:g} m is out of a standing person's reach; give a "
                                 f"point between the floor and {MAX_REACH_HEIGHT:g} m")
        if s.kind == "act":
            if s.action not in vocab:
                raise ValueError(f"{where}: unknown action {s.action!r}; the model knows {', '.join(vocabulary)}")
        needed = {"sit_on": ("sit_down", "sit"), "lie_on": ("lie_down", "lie"), "goto": ("walk",),
                  "reach": ("reach",), "pick_up": ("pick_up",), "put_down": ("put_down",)}.get(s.kind, ())
        lacking = [a for a in needed if a not in vocab]
        if lacking:
            raise ValueError(f"{where}: the model's vocabulary lacks {lacking}; it cannot do this step")
    validate_carry(plan, scene)
