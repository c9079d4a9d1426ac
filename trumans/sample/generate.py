"""Sampling a plan in a scene as one library call: the work behind ``trumans sample`` and ``trumans.generate``.

``generate_sequences`` loads the checkpoint and the scene, builds and validates the plan, samples it
episode by episode (``trumans.sample.rollout.sample_plan``), derives the carried objects' tracks
(§4.2) and returns the sequences with the run's figures. Writing files is the caller's job
(``trumans sample`` exports them; ``trumans.generate`` returns the first sequence).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from trumans.limits import MAX_SAMPLES  # bodies sampled in one batch
from trumans.paths import MODELS_DIR
from trumans.scenes.spec import SCENE_UP_KEY
from trumans.sequence import GOAL_JOINTS_KEY, GOALS_KEY, SAMPLER_CONFIG_KEY, Sequence  # the npz's extra keys

__all__ = ["Generation", "generate_sequences", "check_points_inside", "default_plan", "resolve_plan", "DEFAULT_CHECKPOINT",
           "SAMPLER_CONFIG_KEY", "SCENE_UP_KEY", "MAX_SAMPLES", "GOALS_KEY", "GOAL_JOINTS_KEY"]

DEFAULT_CHECKPOINT = MODELS_DIR / "generator.pt"


@dataclass
class Generation:
    """sequences: one per sample (joints (T, 24, 3) world m, labels, carried objects, the scene's spec in
    ``scene``); figures: the run's figures (goal, seat, penetration, foot skate, seams, speed, carry);
    scene: the scene sampled in (``trumans.scenes.Scene``)."""

    sequences: list[Sequence]
    figures: dict[str, Any]
    scene: Any


def default_plan(sc) -> dict:
    """Walk to a seat, sit, get up, walk elsewhere, a hand action: >= 30 s in most rooms."""
    from trumans.sample.controller import seat_target
    from trumans.sample.plan import far_point

    seats = [o for o in sc.scene.objects.values() if o.category in ("chair", "sofa", "stool") and "seat_center" in o.meta]
    if not seats:
        raise ValueError(f"scene {sc.source} has no chair, sofa or stool for the default plan; give a plan or steps")
    start = sc.free_point()
    seat = min(seats, key=lambda o: -np.linalg.norm(seat_target(o)[0][:2] - start))  # the farthest seat
    away = far_point(sc.walkmap, start)  # kept off the walkable map's edge (trumans.sample.plan)
    return {"start": start.tolist(), "heading": 0.0, "steps": [
        {"do": "sit_on", "object": seat.name, "seconds": 8.0},
        {"do": "stand_up"},
        {"do": "goto", "to": away.tolist()},
        {"do": "act", "action": "drink", "seconds": 5.0},
        {"do": "goto", "to": start.tolist()},
    ]}


def resolve_plan(plan, sc):
    """``plan``: None (the default plan of ``default_plan``), a ``Plan``, a plan dict (docs/generate.md
    "Plans"), a list of step dicts, or a .json/.toml file path -> ``Plan``."""
    from trumans.sample.plan import Plan, load_plan, plan_from_dict

    if plan is None:
        return plan_from_dict(default_plan(sc), name="default")
    if isinstance(plan, Plan):
        return plan
    if isinstance(plan, dict):
        return plan_from_dict(plan, name=str(plan.get("name", "plan")))
    if isinstance(plan, (list, tuple)):
        return plan_from_dict({"steps": list(plan)}, name="steps")
    if isinstance(plan, (str, Path)):
        return load_plan(plan)
    raise TypeError(f"plan must be None, a Plan, a dict, a list of steps or a file path, got {type(plan).__name__}")


def check_points_inside(plan, scene, start: tuple[float, float] | None = None) -> None:
    """Refuse a plan whose start or ``goto`` / ``reach`` points lie outside the scene's horizontal bounds
    (``scene.bounds()``, m): the cheap part of the plan's checks, run before the scene's occupancy grid."""
    b = np.asarray(scene.bounds(), np.float64)
    points = [("start", plan.start if start is None else start)]
    points += [(f"plan step {i + 1} ({s.kind})", s.to if s.kind == "goto" else s.target)
               for i, s in enumerate(plan.steps) if s.kind in ("goto", "reach") and not isinstance(s.target, str)]
    for where, p in points:
        if p is None:
            continue
        xy = np.asarray(p, np.float64)[:2]
        if not ((b[0, :2] <= xy) & (xy <= b[1, :2])).all():
            raise ValueError(f"{where}: point {np.round(xy, 2).tolist()} is outside the scene (x in "
                             f"[{b[0, 0]:.2f}, {b[1, 0]:.2f}], y in [{b[0, 1]:.2f}, {b[1, 1]:.2f}] m); give a point "
                             f"on its floor")


def generate_sequences(plan=None, scene: str | Path = "default", *, checkpoint: str | Path | None = None,
                       seed: int = 0, num_samples: int = 1, config=None, start: tuple[float, float] | None = None,
                       heading: float | None = None, body: np.ndarray | None = None, up: str = "z",
                       device: str = "cpu", max_seconds: float = 600.0, progress: bool = False) -> Generation:
    """Sample ``plan`` (see ``resolve_plan``) in ``scene`` ('default', 'room:SEED', a scene folder or a mesh
    file; ``up`` 'y' for a y-up mesh). checkpoint: generator (default the shipped one); config:
    ``SamplerConfig`` (default = what ``trumans sample`` does); start: floor point (m) and heading (rad
    from +x) overriding the plan's; body: a standing body (24, 3) world m whose bone lengths are kept;
    max_seconds: seconds of motion after which an unfinished plan fails. Arguments are checked before
    any sampling; raises ValueError / FileNotFoundError naming the problem."""
    import torch

    from trumans.eval.synthesis_metrics import motion_figures
    from trumans.model.checkpoint import load_checkpoint
    from trumans.sample.carry import object_tracks
    from trumans.sample.carry_metrics import carry_figures
    from trumans.sample.plan import validate_plan
    from trumans.sample.rollout import body_pose, sample_plan
    from trumans.sample.sampler import EpisodeSampler, SamplerConfig
    from trumans.sample.scene_input import load_sample_scene

    if not 1 <= int(num_samples) <= MAX_SAMPLES:
        raise ValueError(f"num_samples must be in [1, {MAX_SAMPLES}], got {num_samples}")
    if not (np.isfinite(max_seconds) and 0 < max_seconds <= 86400):
        raise ValueError(f"max_seconds must be in (0, 86400], got {max_seconds}")
    if up not in ("z", "y"):
        raise ValueError(f"up must be 'z' or 'y', got {up!r}")
    try:
        dev = torch.device(device)
    except RuntimeError:
        raise ValueError(f"device {device!r} is not a torch device; use cpu or cuda[:N]") from None
    if plan is not None and not isinstance(plan, (dict, list, tuple, str, Path)) and type(plan).__name__ != "Plan":
        raise TypeError(f"plan must be None, a Plan, a dict, a list of steps or a file path, got {type(plan).__name__}")
    config = SamplerConfig() if config is None else config
    ckpt = load_checkpoint(checkpoint or DEFAULT_CHECKPOINT, kind="generator")
    the_plan = None if plan is None else resolve_plan(plan, None)  # the default plan needs the walkable floor
    check = None if the_plan is None else (lambda s: check_points_inside(the_plan, s, start))
    sc = load_sample_scene(None if scene is None else str(scene), up=up, check=check)
    the_plan = resolve_plan(plan, sc) if the_plan is None else the_plan
    if start is not None or heading is not None:
        xy = None if start is None else tuple(float(v) for v in start)
        if xy is not None and (len(xy) != 2 or not np.isfinite(xy).all()):
            raise ValueError(f"start must be a finite floor point (x, y) m, got {start}")
        the_plan = replace(the_plan, start=xy if xy is not None else the_plan.start,
                           heading=float(heading) if heading is not None else the_plan.heading)
    validate_plan(the_plan, sc.scene, ckpt.vocabulary)
    pose = None if body is None else body_pose(np.asarray(body), "body")
    sampler = EpisodeSampler(ckpt, sc.grids, config, device=str(dev))
    xy0 = np.asarray(the_plan.start, np.float64) if the_plan.start is not None else sc.free_point()
    if not sc.walkmap.query(xy0[None])[0]:
        raise ValueError(f"start {np.round(xy0, 2).tolist()} is not on walkable floor; give another start")
    result = sample_plan(ckpt, sampler, sc.scene, sc.walkmap, the_plan, num_samples=int(num_samples), seed=seed,
                         max_seconds=max_seconds, progress=progress, start_xy=xy0, body=pose)
    extra = {SAMPLER_CONFIG_KEY: np.asarray(json.dumps(config.to_dict()))}
    if up == "y":
        extra[SCENE_UP_KEY] = np.asarray("y")
    sequences, carry = [], {}
    for b in range(int(num_samples)):
        tracks, its, info = object_tracks(result.joints[b], result.phase[b], result.phases, sc.scene)  # §4.2
        if b == 0:
            carry = carry_figures(result.joints[b], tracks, its, info, sc.scene, result.phases)
        mine = [(f, j, p) for f, s, j, p in result.goals if s == b]
        goal_rows = np.array([[f, *(np.r_[p, 0.0] if len(p) == 2 else p)] for f, _, p in mine], np.float64).reshape(-1, 4)
        sequences.append(Sequence(joints=result.joints[b], fps=result.fps, actions=result.labels[b],
                                  action_names=list(result.vocabulary), scene=sc.source, objects=tracks,
                                  extra={**extra, GOALS_KEY: goal_rows,  # (K, 4): frame, x, y, z (a pelvis goal: z = 0)
                                         GOAL_JOINTS_KEY: np.asarray([j for _, j, _ in mine], dtype=str)}))
    figures = {"plan": the_plan.name, "scene": sc.source, "samples": int(num_samples),
               "frames": int(result.joints.shape[1]), "seconds_of_motion": round(result.joints.shape[1] / result.fps, 2),
               "episodes": result.episodes, "seconds_per_episode": round(result.seconds_per_episode, 4),
               "realtime_factor": round(result.realtime_factor, 2), **motion_figures(result, sc), **carry}
    return Generation(sequences, figures, sc.scene)
