"""``trumans eval safety``: the worst-case scene-safety benchmark (issue 34).

Plans over the synthesis benchmark's test rooms (``trumans.sample.eval_synthesis.EVAL_ROOM_SEEDS``,
unseen in training) and over room models written as OBJ meshes (``write_room_models``: an L-shaped
room with a pillar, a narrow corridor, a room split by a 5 cm partition; loaded like any mesh scan,
no objects). Plan ``i`` goes to room ``i mod rooms``; its kind (``plan_kind``) cycles through three,
shifted by one each round so that every room gets every kind:

- ``default``: the default plan (sit on the farthest seat, stand up, walk to a far point, drink,
  walk back) from a seeded start and heading (as ``trumans eval synthesis``);
- ``wall``: walk to a seeded point on the edge of the walkable floor (a goal against a wall or
  furniture), drink there, walk to a far point, walk back;
- ``lie``: lie on the bed or sofa, get up, walk to a far point (the room's ``default`` plan where
  nothing can be lain on, and on the mesh rooms the ``wall`` plan).

Every plan runs under each perturbation that stands in for another machine (``PERTURBATIONS``:
``base``; ``threads2``: 2 torch threads instead of 1; ``seed``: the next sampling seed;
``start1mm``: the start moved 1 mm along x): a different floating-point path makes the
autoregressive rollout diverge as another CPU does. Per run (``trumans.eval.safety``):
``crossings`` ((frame, joint) segments through a solid), ``exits`` (frames with the pelvis
outside the room), ``penetration_max_cm`` (the larger of the mesh-exact contact-rule penetration,
``trumans.eval.synthesis_metrics.penetration_cm``, and the joints' core depth in the enclosed
field, where a body past a wall is deep), ``floating_frames`` / ``sinking_frames``,
``feet_off_frames`` (both feet off the floor, not lying), ``seat_err_max_cm`` (every seated frame),
``lying_leg_depth_max_cm``, ``pelvis_speed_max_ms`` (the fastest one-frame pelvis move, m/s: a
body thrown across a frame by a cleanup step; target <= 3), and ``goal_err_cm`` for reference. ``worst`` is the worst of each over
the runs; ``targets`` says which of the issue's targets hold on every run.
"""
from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from trumans import argtypes
from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config

__all__ = ["add_arguments", "run", "evaluate", "PERTURBATIONS", "PLAN_KINDS", "TARGETS", "write_room_models",
           "run_figures", "plan_kind", "parse_only_plans"]

PERTURBATIONS: tuple[str, ...] = ("base", "threads2", "seed", "start1mm")
PLAN_KINDS: tuple[str, ...] = ("default", "wall", "lie")
MESH_ROOMS: tuple[str, ...] = ("l_room", "corridor", "partition")
# (figure, largest value allowed on every run)
TARGETS: tuple[tuple[str, float], ...] = (("crossings", 0), ("exits", 0), ("penetration_max_cm", 5.0),
                                          ("seat_err_max_cm", 5.0), ("lying_leg_depth_max_cm", 3.0),
                                          ("pelvis_speed_max_ms", 3.0))


def add_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.checkpoint_args import add_checkpoint_arguments
    from trumans.common_args import add_device_argument

    add_checkpoint_arguments(p, "generator checkpoint (default: the shipped one)")
    add_device_argument(p)
    p.add_argument("--plans", type=int, default=12, help="plans, spread over the rooms (default 12)")
    p.add_argument("--rooms", type=int, default=6, help="procedural test rooms (1-6, default 6)")
    p.add_argument("--mesh-rooms", type=int, default=3, help=f"OBJ room models among {', '.join(MESH_ROOMS)} "
                   "(0-3, default 3); they are written to --mesh-dir")
    p.add_argument("--mesh-dir", default="out/safety_rooms", help="folder of the OBJ room models (default "
                   "out/safety_rooms)")
    p.add_argument("--demo", action="store_true", help="also run the demo (`trumans sample` with its defaults: the "
                   "default plan in the default room) under every perturbation, as plan 'demo'")
    p.add_argument("--only-plans", default=None, metavar="I,J,...",
                   help="run only these plan numbers (each < --plans; 'demo' for the demo plan), e.g. 45,10,21 to "
                   "rerun failing runs: each plan keeps its room, kind and seeds as in the full benchmark")
    p.add_argument("--perturbations", default=",".join(PERTURBATIONS),
                   help=f"comma-separated among {', '.join(PERTURBATIONS)} (default all)")
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    p.add_argument("--steps", type=int, default=d.steps, help=f"denoising steps (default {d.steps})")
    p.add_argument("--eta", type=float, default=d.eta, help=f"DDIM eta (default {d.eta:g})")
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--max-seconds", type=float, default=120.0, help="seconds of motion after which a plan fails")
    add_guidance_arguments(p)
    add_postprocess_arguments(p)
    p.add_argument("--json", action="store_true", help="print one JSON object (runs, worst, targets)")


# ----------------------------------------------------------------------------- room models

def write_room_models(folder: str | Path, names: tuple[str, ...] = MESH_ROOMS) -> list[Path]:
    """Write OBJ room models (z up, metres; floor slab, 2.5 m walls 12 cm thick, or 5 cm for the
    partition) to ``folder``; returns their paths. ``l_room``: an L-shaped room with a pillar and a
    table-high box; ``corridor``: 1.8 x 6 m with a cabinet-like box; ``partition``: 5 x 4 m split by a
    5 cm wall with a 1 m gap."""
    import trimesh

    def box(lo, hi):
        return trimesh.creation.box(bounds=[lo, hi])

    def rect_walls(W: float, D: float, t: float = 0.12, h: float = 2.5) -> list:
        """Walls outside the interior [0, W] x [0, D]."""
        return [box((-t, -t, 0), (W + t, 0, h)), box((-t, D, 0), (W + t, D + t, h)),
                box((-t, 0, 0), (0, D, h)), box((W, 0, 0), (W + t, D, h))]

    t = 0.12
    rooms = {  # name: (walls and furniture, interior bounds for the floor slab)
        "l_room": ([box((-t, -t, 0), (5 + t, 0, 2.5)), box((5, -t, 0), (5 + t, 2.5 + t, 2.5)),
                    box((2.5, 2.5, 0), (5 + t, 2.5 + t, 2.5)), box((2.5, 2.5, 0), (2.5 + t, 5 + t, 2.5)),
                    box((-t, 5, 0), (2.5 + t, 5 + t, 2.5)), box((-t, -t, 0), (0, 5 + t, 2.5)),
                    box((1.0, 1.0, 0), (1.3, 1.3, 2.5)), box((3.3, 0.0, 0), (4.5, 0.8, 0.75))], (5.0, 5.0)),
        "corridor": (rect_walls(1.8, 6.0) + [box((1.3, 2.5, 0), (1.8, 3.3, 1.9))], (1.8, 6.0)),
        "partition": (rect_walls(5.0, 4.0) + [box((2.5, 0.0, 0), (2.55, 2.6, 2.5)), box((2.5, 3.6, 0), (2.55, 4.0, 2.5))],
                      (5.0, 4.0)),
    }
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        if name not in rooms:
            raise ValueError(f"unknown room model {name!r}; choose among {', '.join(rooms)}")
        parts, (W, D) = rooms[name]
        floor = box((-t - 0.05, -t - 0.05, -0.05), (W + t + 0.05, D + t + 0.05, 0.0))
        mesh = trimesh.util.concatenate([floor, *parts])
        path = folder / f"{name}.obj"
        mesh.export(path)
        paths.append(path)
    return paths


# ----------------------------------------------------------------------------- plans

def _edge_point(wm, start: np.ndarray, rng: np.random.Generator, within: float = 3.0) -> np.ndarray:
    """A seeded walkable cell on the walkable floor's edge (next to a wall or furniture), in start's
    region, 1-``within`` m from it."""
    from scipy import ndimage

    label, _ = ndimage.label(wm.walkable)
    i, j = wm.index(start)
    region = label == label[i, j]
    edge = region & ~ndimage.binary_erosion(wm.walkable)
    idx = np.argwhere(edge)
    d = np.linalg.norm(wm.centers(idx) - start, axis=1)
    pick = idx[(d > 1.0) & (d < within)] if ((d > 1.0) & (d < within)).any() else idx
    return wm.centers(pick[rng.integers(len(pick))])


def parse_only_plans(text: str | None, plans: int, demo: bool) -> tuple[set[int] | None, bool]:
    """``--only-plans`` ("45,10,demo") -> (plan numbers to run or None for all, whether to run the demo).
    Every number must be in [0, plans): plan i keeps the room, kind and seeds it has in the full run."""
    if text is None:
        return None, demo
    items = [t.strip() for t in text.split(",") if t.strip()]
    nums = [t for t in items if t != "demo"]
    if not items or not all(t.isdigit() and int(t) < plans for t in nums):
        raise ValueError(f"--only-plans must be comma-separated plan numbers in [0, --plans={plans}) or 'demo', "
                         f"got {text!r}")
    return {int(t) for t in nums}, "demo" in items


def plan_kind(i: int, rooms: int) -> str:
    """The kind of plan ``i`` when plans are dealt to ``rooms`` rooms in turn (plan i to room i mod rooms): the
    kinds cycle, shifted by one on every round, so each room gets every kind (a plain ``i mod 3`` would give a
    room the same kind every round whenever ``rooms`` is a multiple of 3)."""
    rooms = max(rooms, 1)
    return PLAN_KINDS[(i % rooms + i // rooms) % len(PLAN_KINDS)]


def _plan(sc, kind: str, seed: int, name: str):
    """The seeded plan of ``kind`` (module doc) in the sample scene ``sc`` -> (Plan, kind used)."""
    from trumans.sample.generate import default_plan
    from trumans.sample.plan import far_point, plan_from_dict

    from scipy import ndimage

    rng = np.random.default_rng(seed)
    label, _ = ndimage.label(sc.walkmap.walkable)  # the walkable region around the room's centre (a mesh
    i, j = sc.walkmap.index(sc.free_point())       # room's map also has free floor outside its walls)
    free = sc.walkmap.centers(np.argwhere(label == label[i, j]))
    start = free[rng.integers(len(free))]
    heading = float(rng.uniform(-np.pi, np.pi))
    seats = [o for o in sc.scene.objects.values() if "seat_center" in o.meta and o.category in ("chair", "sofa", "stool")]
    beds = [o for o in sc.scene.objects.values() if "lie_center" in o.meta]
    if kind == "lie" and not beds:
        kind = "default" if seats else "wall"
    if kind == "default" and not seats:
        kind = "wall"
    if kind == "default":
        d = default_plan(sc)
        d["start"], d["heading"] = start.tolist(), heading
        d["steps"][-1]["to"] = d["start"]
    elif kind == "wall":
        d = {"start": start.tolist(), "heading": heading, "steps": [
            {"do": "goto", "to": _edge_point(sc.walkmap, start, rng).tolist()},
            {"do": "act", "action": "drink", "seconds": 4.0},
            {"do": "goto", "to": far_point(sc.walkmap, start).tolist()},
            {"do": "goto", "to": start.tolist()}]}
    else:
        bed = beds[int(rng.integers(len(beds)))]
        d = {"start": start.tolist(), "heading": heading, "steps": [
            {"do": "lie_on", "object": bed.name, "seconds": 5.0}, {"do": "get_up"},
            {"do": "goto", "to": far_point(sc.walkmap, start).tolist()}]}
    return plan_from_dict(d, name=name), kind


# ----------------------------------------------------------------------------- figures

def run_figures(result, sc, sdf, contact_scene) -> dict:
    """The safety figures (module doc) of the first sample of a ``SampleResult`` in the sample scene
    ``sc``; ``sdf``: the scene's field (``SceneSDF``, dynamic objects at their poses);
    ``contact_scene``: its ``trumans.contacts.rule.ContactScene`` (floor excluded)."""
    from trumans.eval import safety
    from trumans.eval.synthesis_metrics import goal_errors_cm, pelvis_speed_max, penetration_cm
    from trumans.sample.cleanup.support_lift import support_weights
    from trumans.skeleton import JOINT_INDEX

    J = result.joints[0].astype(np.float64)
    T = len(J)
    phase = result.phase[0]
    kinds = np.array([result.phases[i].kind if i >= 0 else "" for i in phase])
    upright = support_weights(result.labels[0], result.vocabulary) >= 1.0
    not_lying = ~np.isin(kinds, ("lie_down", "lie", "get_up"))
    seat_h = np.full(T, np.nan)
    surface = np.full(T, np.nan)
    over = np.zeros((T, len(safety.LEG_JOINTS)), bool)
    for i, p in enumerate(result.phases):
        sel = phase == i
        if p.kind == "sit" and "seat_height" in p.info:
            seat_h[sel] = p.info["seat_height"]
        if p.kind == "lie" and "surface_height" in p.info:
            surface[sel] = p.info["surface_height"]
            obj = sc.scene.objects[p.info["object"]]
            inv = np.linalg.inv(obj.pose)
            local = J[sel][:, list(safety.LEG_JOINTS)] @ inv[:3, :3].T + inv[:3, 3]
            lo, hi = np.asarray(obj.mesh.bounds)
            over[sel] = np.all((local[..., :2] >= lo[:2]) & (local[..., :2] <= hi[:2]), axis=-1)
    _, pen_mesh = penetration_cm(J, contact_scene)
    depth = safety.core_depths(J, sdf)
    cross = safety.crossings(J, sdf)
    exits = safety.room_exits(J[:, JOINT_INDEX["pelvis"], :2], sdf)
    seat = safety.seat_errors(J, seat_h, result.sit_offset)
    legs = safety.lying_leg_depths(J, surface, over)
    goals = [(f, j, p) for (f, b, j, p) in result.goals if b == 0]
    ge = goal_errors_cm(J, goals)
    worst = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return {
        "frames": T,
        "crossings": int(cross.sum()),
        "crossing_at": [[int(t), str(list(JOINT_INDEX)[j])] for t, j in np.argwhere(cross)[:20]],
        "exits": int(exits.sum()),
        "penetration_max_cm": round(max(pen_mesh, float(depth.max()) * 100.0), 2),
        "mesh_penetration_max_cm": round(pen_mesh, 2),
        "core_depth_max_cm": round(float(depth.max()) * 100.0, 2),
        "core_depth_at": [int(worst[0]), str(list(JOINT_INDEX)[worst[1]])],
        "floating_frames": int(safety.floating_frames(J, upright).sum()),
        "sinking_frames": int(safety.sinking_frames(J).sum()),
        "feet_off_frames": int(safety.feet_off_frames(J, not_lying).sum()),
        "seat_err_max_cm": round(float(seat.max()) * 100.0, 2) if seat.size else None,
        "lying_leg_depth_max_cm": round(float(legs.max()) * 100.0, 2) if legs.size else None,
        "goal_err_cm": round(float(ge.mean()), 2) if ge.size else None,
        "pelvis_speed_max_ms": round(pelvis_speed_max(J, result.fps), 2),
    }


def _worst(runs: list[dict]) -> dict:
    keys = ("crossings", "exits", "penetration_max_cm", "mesh_penetration_max_cm", "core_depth_max_cm",
            "floating_frames", "sinking_frames", "feet_off_frames", "seat_err_max_cm", "lying_leg_depth_max_cm",
            "goal_err_cm", "pelvis_speed_max_ms")
    out = {}
    for k in keys:
        vals = [r[k] for r in runs if r.get(k) is not None]
        out[k] = max(vals) if vals else None
        if vals:
            out[f"{k}_run"] = runs[int(np.argmax(vals))]["run"]
    out["failed_runs"] = [r["run"] for r in runs if "error" in r]
    return out


def evaluate(ckpt_path, plans: int, rooms: int, mesh_rooms: int, perturbations: tuple[str, ...], seed: int,
             config=None, mesh_dir: str | Path = "out/safety_rooms", max_seconds: float = 120.0,
             log=None, demo: bool = False, device: str = "cpu", only: set[int] | None = None) -> dict:
    """Run the benchmark (module doc) -> {"runs": [...], "worst": {...}, "targets": {...}}; ``demo``:
    also the default plan in the default room from its default start (what ``make demo`` samples,
    seed 0), under every perturbation ('seed': seed 1); ``only``: run just these plan numbers (each in
    the room, with the kind and seeds it has among ``plans``), None = all."""
    import torch

    from trumans.contacts.rule import ContactScene
    from trumans.model.checkpoint import load_checkpoint
    from trumans.sample.eval_synthesis import EVAL_ROOM_SEEDS
    from trumans.sample.rollout import sample_plan
    from trumans.sample.sampler import EpisodeSampler, SamplerConfig
    from trumans.sample.scene_input import load_sample_scene

    config = SamplerConfig() if config is None else config
    ckpt = load_checkpoint(ckpt_path, kind="generator")
    torch.set_grad_enabled(False)
    specs = [f"room:{s}" for s in EVAL_ROOM_SEEDS[:rooms]]
    specs += [str(p) for p in write_room_models(mesh_dir, MESH_ROOMS[:mesh_rooms])] if mesh_rooms else []
    threads = torch.get_num_threads()
    runs: list[dict] = []
    jobs = [("default", ["demo"])] if demo else []
    jobs += [(spec, [i for i in range(plans) if i % len(specs) == r and (only is None or i in only)])
             for r, spec in enumerate(specs)]
    for spec, todo in jobs:
        if not todo:
            continue
        sc = load_sample_scene(spec)
        sampler = EpisodeSampler(ckpt, sc.grids, config, device=device)
        sdf = sampler.scene_sdf_all if sampler.scene_sdf_all is not None else None
        if sdf is None:
            from trumans.scenes.sdf import SceneSDF
            sdf = SceneSDF(sc.occupancy)
        contact = ContactScene(sc.scene, floor=False)
        for i in todo:
            if i == "demo":
                from trumans.sample.generate import resolve_plan
                plan, kind, base_seed = resolve_plan(None, sc), "demo", 0
            else:
                plan, kind = _plan(sc, plan_kind(i, len(specs)), seed * 1000 + i, f"safety_{i}")
                base_seed = seed + i
            for pert in perturbations:
                s, start = base_seed, np.asarray(plan.start, np.float64)
                if pert == "seed":
                    s += 1 if i == "demo" else 100_000
                if pert == "start1mm":
                    start = start + np.array([0.001, 0.0])
                torch.set_num_threads(2 if pert == "threads2" else threads)
                p = replace(plan, start=tuple(start.tolist()))
                name = f"{i}:{kind}:{Path(spec).stem}:{pert}"
                tic = time.perf_counter()
                try:
                    res = sample_plan(ckpt, sampler, sc.scene, sc.walkmap, p, seed=s, max_seconds=max_seconds,
                                      start_xy=start)
                    fig = {"run": name, **run_figures(res, sc, sdf, contact)}
                except ValueError as e:  # a plan the body did not finish: a failed run, reported
                    fig = {"run": name, "error": str(e)}
                finally:
                    torch.set_num_threads(threads)
                fig["seconds"] = round(time.perf_counter() - tic, 1)
                runs.append(fig)
                if log is not None:
                    log(json.dumps(fig))
    done = [r for r in runs if "error" not in r]
    worst = _worst(runs)
    targets = {k: bool(done) and all((r[k] if r[k] is not None else 0) <= lim for r in done) for k, lim in TARGETS}
    targets["all_runs_finished"] = len(done) == len(runs)
    return {"plans": plans, "perturbations": list(perturbations), "runs": runs, "worst": worst, "targets": targets}


def run(args: argparse.Namespace) -> int:
    import sys

    from trumans.checkpoint_args import resolve_checkpoint
    from trumans.sample.generate import DEFAULT_CHECKPOINT

    resolve_checkpoint(args)
    perts = tuple(p.strip() for p in args.perturbations.split(",") if p.strip())
    bad = [p for p in perts if p not in PERTURBATIONS]
    if bad or not perts:
        raise ValueError(f"--perturbations must name some of {', '.join(PERTURBATIONS)}, got {args.perturbations!r}")
    if args.plans < 1 or not 1 <= args.rooms <= 6 or not 0 <= args.mesh_rooms <= len(MESH_ROOMS):
        raise ValueError(f"need --plans >= 1, --rooms in [1, 6] and --mesh-rooms in [0, {len(MESH_ROOMS)}], got "
                         f"{args.plans}, {args.rooms}, {args.mesh_rooms}")
    if not (np.isfinite(args.max_seconds) and args.max_seconds > 0):
        raise ValueError(f"--max-seconds must be > 0, got {args.max_seconds}")
    only, demo = parse_only_plans(args.only_plans, args.plans, args.demo)
    figs = evaluate(args.checkpoint or DEFAULT_CHECKPOINT, args.plans, args.rooms, args.mesh_rooms, perts, args.seed,
                    sampler_config(args), args.mesh_dir, args.max_seconds,
                    log=lambda line: print(line, file=sys.stderr, flush=True), demo=demo, device=args.device,
                    only=only)
    if args.json:
        from trumans.summary import print_summary

        print_summary(figs)
    else:
        for r in figs["runs"]:
            print(r)
        print("worst:", figs["worst"])
        print("targets:", figs["targets"])
    return 0
