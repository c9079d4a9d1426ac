"""Moved objects after the body (``trumans.sample.carry``, TRUMANS §4.2) on the shipped generator.

    python benchmarks/carry_objects.py --json            # three plans in the default room, seeds 0..2
    python benchmarks/carry_objects.py --smooth 0.1 1 10 # the smoothness weight's effect
    python benchmarks/carry_objects.py --reach both      # without / with the reach cleanup, same seeds

Plans (default room, procedural room 2): pick up bottle_0 from the cabinet, walk, put it on the
table; open and close the door; open and close a drawer. For each plan and seed: the body is
sampled (20 DDIM steps), the objects are moved (``object_tracks``) and the figures of
``trumans.sample.carry_metrics`` are printed (mean over the seeds), with ``_static`` (objects left where
they were, the output before this step) and ``_init`` (hand-driven, before the optimisation).
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from trumans.sample.carry import CarryConfig, object_tracks
from trumans.sample.carry_metrics import carry_figures
from trumans.sample.cli import DEFAULT_CHECKPOINT
from trumans.sample.plan import plan_from_dict, validate_plan
from trumans.sample.rollout import sample_plan
from trumans.sample.cleanup import CleanupConfig
from trumans.sample.sampler import EpisodeSampler, SamplerConfig
from trumans.sample.scene_input import load_sample_scene
from trumans.model.checkpoint import load_checkpoint

PLANS = {
    "carry": {"start": [2.4, 2.4], "steps": [{"do": "pick_up", "object": "bottle_0"}, {"do": "goto", "to": [2.4, 2.4]},
                                             {"do": "put_down", "object": "bottle_0", "target": "table_0"}]},
    "door": {"start": [3.5, 2.6], "steps": [{"do": "open", "object": "door_0"}, {"do": "close", "object": "door_0"}]},
    "drawer": {"start": [2.0, 3.0], "steps": [{"do": "open", "object": "cabinet_0_drawer_1"},
                                              {"do": "close", "object": "cabinet_0_drawer_1"}]},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--smooth", type=float, nargs="+", default=[CarryConfig().smooth])
    ap.add_argument("--reach", choices=("on", "off", "both"), default="on",
                    help="the arm reach cleanup (sample/reach_cleanup.py): on (default), off, or both side by side")
    ap.add_argument("--out", default=None, help="write each plan's seed-0 sequence (npz + glb) under this stem")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    ckpt = load_checkpoint(DEFAULT_CHECKPOINT, kind="generator")
    sc = load_sample_scene("default")
    modes = {"on": (True,), "off": (False,), "both": (False, True)}[args.reach]
    samplers = {on: EpisodeSampler(ckpt, sc.grids, SamplerConfig(steps=20, goal_guidance=0.0, action_scale=1.0,
                                                                     cleanup=CleanupConfig().switched(reach=on))) for on in modes}
    report: dict = {}
    for name, d in PLANS.items():
        plan = plan_from_dict(d, name=name)
        validate_plan(plan, sc.scene, ckpt.vocabulary)
        for smooth, on in ((s, on) for s in args.smooth for on in modes):
            sampler = samplers[on]
            rows, secs = [], []
            for seed in range(args.seeds):
                res = sample_plan(ckpt, sampler, sc.scene, sc.walkmap, plan, seed=seed)
                tic = time.perf_counter()
                tracks, its, inits = object_tracks(res.joints[0], res.phase[0], res.phases, sc.scene,
                                                   CarryConfig(smooth=smooth))
                secs.append(time.perf_counter() - tic)
                rows.append(carry_figures(res.joints[0], tracks, its, inits, sc.scene, res.phases))
                if args.out and seed == 0 and smooth == args.smooth[0] and on == modes[-1]:
                    from trumans.viz.export import export
                    from trumans.sequence import Sequence
                    seq = Sequence(joints=res.joints[0], fps=res.fps, actions=res.labels[0],
                                   action_names=list(res.vocabulary), scene=sc.source, objects=tracks)
                    export(seq, f"{args.out}_{name}", {"npz", "glb", "gif"}, scene=sc.scene)
            keys = sorted({k for r in rows for k in r})
            fig = {k: round(float(np.mean([r[k] for r in rows if k in r])), 2) for k in keys}
            fig["optimise_seconds"] = round(float(np.mean(secs)), 3)
            key = f"{name}@smooth={smooth:g}" + ("" if args.reach == "on" else f"@reach={'on' if on else 'off'}")
            report[key] = fig
            if not args.json:
                print(key, fig, flush=True)
    if args.json:
        print(json.dumps(report))


if __name__ == "__main__":
    main()
