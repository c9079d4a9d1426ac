"""``trumans sample``: a long motion in a scene from a plan (TRUMANS §4; the sampling issue).

    trumans sample --out out/walk_sit                              # the default plan in the default room
    trumans sample --plan examples/plan_sit_drink.toml --out out/x --formats npz,gif,glb   # a plan file
    trumans sample --goto 2.0,1.5 --sit-on chair_0:6 --stand-up --act drink:3 --goto 0.8,0.8 --out out/y
    trumans sample --scene room:7 --goto 1.5,2.5 --out out/r7       # another procedural room
    trumans sample --scene examples/room_mesh.obj --sit-on seat_0 --out out/z   # any mesh (--up y: a y-up file)

Step flags keep their order on the command line. Without a plan or step flags the default plan
runs: walk, sit on a seat, get up, walk, a hand action (>= 30 s).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config
from trumans.sample.generate import DEFAULT_CHECKPOINT, MAX_SAMPLES, SAMPLER_CONFIG_KEY, default_plan
from trumans import argtypes
from trumans.common_args import add_device_argument, add_no_progress_argument, out_help
from trumans.threads import add_threads_argument, set_threads

__all__ = ["add_arguments", "run", "steps_from_flags", "body_frame", "DEFAULT_CHECKPOINT", "SAMPLER_CONFIG_KEY",
           "MAX_SAMPLES", "default_plan"]
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
    p.add_argument("--out", required=True, help=out_help("stem", "writes STEM.npz (+ STEM.bvh, .gif ... for the other "
                                                             "--formats; STEM_00.npz ... with --num-samples)"))
    p.add_argument("--formats", default="npz,png", help=f"comma-separated among {','.join(FORMATS)} (default npz,png)")
    p.add_argument("--num-samples", type=argtypes.int_in(1, MAX_SAMPLES, limit="MAX_SAMPLES"), default=1,
                   help=f"variations sampled in one batch (default 1, at most {MAX_SAMPLES})")
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    p.add_argument("--steps", type=int, default=d.steps, help=f"denoising steps (respaced; default {d.steps})")
    p.add_argument("--eta", type=float, default=d.eta, help=f"DDIM eta (0 deterministic, 1 ancestral; default {d.eta:g})")
    add_guidance_arguments(p)
    add_postprocess_arguments(p)
    p.add_argument("--max-seconds", type=argtypes.float_in(0.0, 86400.0, lo_open=True), default=600.0,
                   help="give up when the plan is not done by then (seconds of motion, at most a day)")
    add_device_argument(p)
    add_threads_argument(p)
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (same seed -> same motion)")
    p.add_argument("--json", action="store_true", help="print one JSON object of figures as the last line")
    add_no_progress_argument(p)


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


def run(args: argparse.Namespace) -> int:
    from trumans.sample.generate import generate_sequences
    from trumans.sample.plan import plan_from_dict
    from trumans.viz.export import export

    formats = {f.strip() for f in args.formats.split(",") if f.strip()}
    bad = formats - set(FORMATS)
    if bad or not formats:
        raise ValueError(f"--formats must name some of {','.join(FORMATS)}, got {args.formats!r}")
    from trumans.out_paths import check_out, refuse_dataset_file
    from trumans.viz.export import export_paths

    check_out(args.out, "stem")
    for b in range(args.num_samples):  # before sampling: no output may replace a dataset's file
        stem = Path(args.out) if args.num_samples == 1 else Path(args.out).with_name(f"{Path(args.out).name}_{b:02d}")
        for p in export_paths(stem, formats).values():
            refuse_dataset_file(p)
    flags = list(getattr(args, "plan_steps", None) or [])
    if args.plan and flags:
        raise ValueError("give either --plan FILE or step flags (--goto, --sit-on, ...), not both")
    plan = args.plan or (plan_from_dict({"steps": steps_from_flags(flags)}, name="flags") if flags else None)
    body = None if args.body is None else body_frame(args.body)
    set_threads(args.threads)
    gen = generate_sequences(plan, args.scene, checkpoint=args.checkpoint, seed=args.seed,
                             num_samples=args.num_samples, config=sampler_config(args),
                             start=None if args.start is None else _xy(args.start, 2, "--start"),
                             heading=args.heading, body=body, up=args.up, device=args.device,
                             max_seconds=args.max_seconds, progress=not args.no_progress)
    out = Path(args.out)
    written: list[str] = []
    scene = gen.scene
    for b, seq in enumerate(gen.sequences):
        stem = out if args.num_samples == 1 else out.with_name(f"{out.name}_{b:02d}")
        written += [str(p) for p in export(seq, stem, formats, scene=scene).values()]
    summary = {**gen.figures, "written": written}
    if args.json:
        from trumans.summary import print_summary

        print_summary(summary)
    else:
        for k, v in summary.items():
            print(f"{k}: {v}", file=sys.stdout)
    return 0
