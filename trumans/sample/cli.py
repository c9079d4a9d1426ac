"""``trumans sample``: a long motion in a scene from a plan (TRUMANS §4; the sampling issue).

    trumans sample --out out/walk_sit                              # the default plan in the default room
    trumans sample --plan plan.toml --scene data/synth/scenes/room_000 --out out/x --formats npz,gif,glb
    trumans sample --goto 2.0,1.5 --sit-on chair_0 --act drink:3 --stand-up --goto 1,1 --out out/y
    trumans sample --scene scan.ply --up y --goto 1,2 --out out/z  # any mesh trimesh reads

Step flags keep their order on the command line. Without a plan or step flags the default plan
runs: walk, sit on a seat, get up, walk, a hand action (>= 30 s).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config
from trumans.paths import MODELS_DIR
from trumans import argtypes

__all__ = ["add_arguments", "run", "DEFAULT_CHECKPOINT", "SAMPLER_CONFIG_KEY", "MAX_SAMPLES"]

MAX_SAMPLES = 256  # --num-samples: one batch of bodies, each a few MB per episode

DEFAULT_CHECKPOINT = MODELS_DIR / "generator.pt"
# the sequence's ``extra`` entry with the sampler config used, JSON (``SamplerConfig.to_dict``);
# ``SamplerConfig.from_dict(json.loads(...))`` rebuilds it
SAMPLER_CONFIG_KEY = "sampler_config"
FORMATS = ("npz", "bvh", "gif", "mp4", "png", "glb")


class _StepAction(argparse.Action):
    """Appends (kind, value) to ``args.steps`` so that steps keep their command-line order."""

    def __call__(self, parser, namespace, values, option_string=None):
        steps = list(getattr(namespace, "plan_steps", None) or [])
        steps.append((self.dest, values))
        namespace.plan_steps = steps


def _xy(text: str, n: int, what: str) -> list[float]:
    try:
        v = [float(t) for t in text.split(",")]
    except ValueError:
        v = []
    if len(v) != n or not np.isfinite(v).all():
        raise ValueError(f"{what} must be {n} comma-separated numbers like {','.join(['1.0'] * n)}, got {text!r}")
    return v


def steps_from_flags(flags: list[tuple[str, str | None]]) -> list[dict]:
    """[(flag dest, value)] -> plan step dicts (``trumans.sample.plan`` form)."""
    out: list[dict] = []
    for kind, value in flags:
        if kind == "goto":
            out.append({"do": "goto", "to": _xy(value, 2, "--goto")})
        elif kind in ("sit_on", "lie_on"):
            name, _, secs = value.partition(":")
            d = {"do": kind, "object": name}
            if secs:
                d["seconds"] = _xy(secs, 1, f"--{kind.replace('_', '-')} NAME:SECONDS seconds")[0]
            out.append(d)
        elif kind in ("stand_up", "get_up"):
            out.append({"do": kind})
        elif kind == "act":
            name, _, secs = value.partition(":")
            d = {"do": "act", "action": name}
            if secs:
                d["seconds"] = _xy(secs, 1, "--act NAME:SECONDS seconds")[0]
            out.append(d)
        elif kind == "reach":
            target, _, hand = value.partition(":")
            d = {"do": "reach", "target": target if any(c.isalpha() for c in target.replace("e", "")) or
                 target.count(",") != 2 else _xy(target, 3, "--reach X,Y,Z")}
            if hand:
                d["hand"] = hand
            out.append(d)
        elif kind == "put_down":
            name, _, where = value.partition(":")
            d = {"do": "put_down", "object": name}
            if where:
                d["target"] = where if where.count(",") != 2 else _xy(where, 3, "--put-down NAME:X,Y,Z")
            out.append(d)
        else:
            out.append({"do": kind, "object": value})
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = __doc__
    p.add_argument("--checkpoint", default=None, help="generator checkpoint (default: the shipped models/generator.pt)")
    p.add_argument("--scene", default="default",
                   help="scene folder, mesh file, 'default' (the default room) or room:SEED (a procedural room)")
    p.add_argument("--up", choices=("z", "y"), default="z", help="up axis of a mesh file given as --scene")
    p.add_argument("--plan", default=None, help="plan file (.json or .toml); see the Plans section of docs/generate.md")
    p.add_argument("--start", default=None, help="start floor point X,Y (m); default: the plan's, else the room centre")
    p.add_argument("--heading", type=float, default=None, help="start heading (rad, from +x)")
    p.add_argument("--body", default=None, metavar="SEQ.npz[:FRAME]",
                   help="sample with the body of a standing frame of a sequence (default frame 0; its bone lengths "
                        "are kept); default: the checkpoint's start body")
    g = p.add_argument_group("plan steps (in command-line order)")
    g.add_argument("--goto", action=_StepAction, metavar="X,Y", help="walk to a floor point")
    g.add_argument("--sit-on", dest="sit_on", action=_StepAction, metavar="NAME[:S]", help="sit on a seat for S s")
    g.add_argument("--lie-on", dest="lie_on", action=_StepAction, metavar="NAME[:S]", help="lie on a bed/sofa")
    g.add_argument("--stand-up", dest="stand_up", action=_StepAction, nargs=0, help="stand up from the seat")
    g.add_argument("--get-up", dest="get_up", action=_StepAction, nargs=0, help="get up from lying")
    g.add_argument("--act", action=_StepAction, metavar="ACTION[:S]", help="an action (drink, phone_call, type, ...)")
    g.add_argument("--reach", action=_StepAction, metavar="NAME|X,Y,Z[:HAND]", help="reach an object or point")
    g.add_argument("--pick-up", dest="pick_up", action=_StepAction, metavar="NAME", help="pick an object up")
    g.add_argument("--put-down", dest="put_down", action=_StepAction, metavar="NAME[:SURFACE|:X,Y,Z]",
                   help="put a held object down (on a surface object or at a point; default where it was)")
    g.add_argument("--open", dest="open", action=_StepAction, metavar="NAME", help="open a door or drawer")
    g.add_argument("--close", dest="close", action=_StepAction, metavar="NAME", help="close a door or drawer")
    p.add_argument("--out", required=True, help="output path stem: writes STEM.npz (+ other --formats)")
    p.add_argument("--formats", default="npz,png", help=f"comma-separated among {','.join(FORMATS)} (default npz,png)")
    p.add_argument("--num-samples", type=argtypes.int_in(1, MAX_SAMPLES), default=1,
                   help=f"variations sampled in one batch (default 1, at most {MAX_SAMPLES})")
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    p.add_argument("--steps", type=int, default=d.steps, help=f"denoising steps (respaced; default {d.steps})")
    p.add_argument("--eta", type=float, default=d.eta, help=f"DDIM eta (0 deterministic, 1 ancestral; default {d.eta:g})")
    add_guidance_arguments(p)
    add_postprocess_arguments(p)
    p.add_argument("--max-seconds", type=argtypes.float_in(0.0, 86400.0, lo_open=True), default=600.0,
                   help="give up when the plan is not done by then (seconds of motion, at most a day)")
    p.add_argument("--device", type=argtypes.device, default="cpu", help="torch device (cpu, cuda, cuda:1)")
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--json", action="store_true", help="print one JSON object of figures as the last line")
    p.add_argument("--no-progress", action="store_true")


def body_frame(spec: str) -> np.ndarray:
    """``--body SEQ.npz[:FRAME]`` -> that frame's joints (24, 3) world m (``rollout.body_pose`` checks it)."""
    from trumans.sequence import load_sequence

    path, frame = spec, 0
    head, sep, tail = spec.rpartition(":")
    if sep and tail.lstrip("-").isdigit():
        path, frame = head, int(tail)
    if not Path(path).is_file():
        raise FileNotFoundError(f"--body: sequence {path} does not exist; give SEQ.npz[:FRAME]")
    joints = load_sequence(path).joints
    if not -len(joints) <= frame < len(joints):
        raise ValueError(f"--body: {path} has {len(joints)} frames, frame {frame} is out of range")
    return np.asarray(joints[frame])


def default_plan(sc) -> dict:
    """Walk to a seat, sit, get up, walk elsewhere, a hand action: >= 30 s in most rooms."""
    from trumans.sample.controller import seat_target

    seats = [o for o in sc.scene.objects.values() if o.category in ("chair", "sofa", "stool") and "seat_center" in o.meta]
    if not seats:
        raise ValueError(f"scene {sc.source} has no chair, sofa or stool for the default plan; give --plan or steps")
    start = sc.free_point()
    seat = min(seats, key=lambda o: -np.linalg.norm(seat_target(o)[0][:2] - start))  # the farthest seat
    far = np.argwhere(sc.walkmap.walkable)
    pts = sc.walkmap.centers(far)
    d = np.linalg.norm(pts - start, axis=1)
    away = pts[int(np.argmax(np.where(d < 3.0, d, 0.0)))]
    return {"start": start.tolist(), "heading": 0.0, "steps": [
        {"do": "sit_on", "object": seat.name, "seconds": 8.0},
        {"do": "stand_up"},
        {"do": "goto", "to": away.tolist()},
        {"do": "act", "action": "drink", "seconds": 5.0},
        {"do": "goto", "to": start.tolist()},
    ]}


def run(args: argparse.Namespace) -> int:
    import torch

    from trumans.model.checkpoint import load_checkpoint
    from trumans.sequence import Sequence

    from trumans.sample.plan import load_plan, plan_from_dict, validate_plan
    from trumans.sample.rollout import body_pose, sample_plan
    from trumans.sample.sampler import EpisodeSampler
    from trumans.sample.scene_input import load_sample_scene
    from trumans.eval.synthesis_metrics import motion_figures

    formats = {f.strip() for f in args.formats.split(",") if f.strip()}
    bad = formats - set(FORMATS)
    if bad or not formats:
        raise ValueError(f"--formats must name some of {','.join(FORMATS)}, got {args.formats!r}")
    if args.num_samples < 1:
        raise ValueError(f"--num-samples must be >= 1, got {args.num_samples}")
    if not args.max_seconds > 0:
        raise ValueError(f"--max-seconds must be > 0, got {args.max_seconds}")
    try:
        device = torch.device(args.device)
    except RuntimeError:
        raise ValueError(f"--device {args.device!r} is not a torch device; use cpu or cuda[:N]") from None
    ckpt = load_checkpoint(args.checkpoint or DEFAULT_CHECKPOINT, kind="generator")
    sc = load_sample_scene(args.scene, up=args.up)
    flags = list(getattr(args, "plan_steps", None) or [])
    if args.plan and flags:
        raise ValueError("give either --plan FILE or step flags (--goto, --sit-on, ...), not both")
    if args.plan:
        plan = load_plan(args.plan)
    elif flags:
        plan = plan_from_dict({"steps": steps_from_flags(flags)}, name="flags")
    else:
        plan = plan_from_dict(default_plan(sc), name="default")
    if args.start is not None or args.heading is not None:
        from dataclasses import replace
        plan = replace(plan, start=tuple(_xy(args.start, 2, "--start")) if args.start else plan.start,
                       heading=args.heading if args.heading is not None else plan.heading)
    validate_plan(plan, sc.scene, ckpt.vocabulary)
    body = None if args.body is None else body_pose(body_frame(args.body), f"--body {args.body}")
    config = sampler_config(args)
    sampler = EpisodeSampler(ckpt, sc.grids, config, device=str(device))
    start = np.asarray(plan.start, np.float64) if plan.start is not None else sc.free_point()
    if not sc.walkmap.query(start[None])[0]:
        raise ValueError(f"start {np.round(start, 2).tolist()} is not on walkable floor; give another --start")
    result = sample_plan(ckpt, sampler, sc.scene, sc.walkmap, plan, num_samples=args.num_samples, seed=args.seed,
                         max_seconds=args.max_seconds, progress=not args.no_progress, start_xy=start,
                         body=body)
    out = Path(args.out)
    written: list[str] = []
    from trumans.viz.export import export

    from trumans.sample.carry import object_tracks
    from trumans.sample.carry_metrics import carry_figures

    carry: dict = {}
    for b in range(args.num_samples):
        tracks, its, info = object_tracks(result.joints[b], result.phase[b], result.phases, sc.scene)  # §4.2
        if b == 0:
            carry = carry_figures(result.joints[b], tracks, its, info, sc.scene, result.phases)
        seq = Sequence(joints=result.joints[b], fps=result.fps, actions=result.labels[b],
                       action_names=list(result.vocabulary), scene=sc.source, objects=tracks,
                       extra={SAMPLER_CONFIG_KEY: np.asarray(json.dumps(config.to_dict()))})
        stem = out if args.num_samples == 1 else out.with_name(f"{out.name}_{b:02d}")
        written += [str(p) for p in export(seq, stem, formats, scene=sc.scene).values()]
    figures = motion_figures(result, sc)
    summary = {"plan": plan.name, "scene": sc.source, "samples": args.num_samples, "frames": int(result.joints.shape[1]),
               "seconds_of_motion": round(result.joints.shape[1] / result.fps, 2), "episodes": result.episodes,
               "seconds_per_episode": round(result.seconds_per_episode, 4),
               "realtime_factor": round(result.realtime_factor, 2), **figures, **carry, "written": written}
    if args.json:
        print(json.dumps(summary))
    else:
        for k, v in summary.items():
            print(f"{k}: {v}", file=sys.stdout)
    return 0
