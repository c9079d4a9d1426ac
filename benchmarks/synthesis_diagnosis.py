"""Where the synthesis benchmark's penetration and foot skate come from.

    python benchmarks/synthesis_diagnosis.py [CHECKPOINT] [--rooms 2] [--seed 0] [--save out.npz] [--json]
        [--no-foot-cleanup] [--no-penetration-guidance] ...   (the switches of ``trumans eval synthesis``)

Runs the plans of ``trumans eval synthesis`` (same rooms, seeds, sampler) and prints, per room:
the deepest penetrations by (joint, object, phase kind) with their frame and depth, the share of
penetration coming from each phase kind, and the foot-skate figure broken down by contact-run
length and by the foot's speed inside the runs (how much of it is slow planted feet sliding and
how much is low fast swings counted as contacts), and the seat height error against the data's
seated pelvis offset and against ``seat_clearance`` alone (the offset used before). ``--save`` writes the joints, phases and seams.
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config  # noqa: E402
from trumans.sample.sampler import SamplerConfig  # noqa: E402


def penetration_report(J: np.ndarray, sc, res, top: int = 8) -> dict:
    """J (T, 24, 3) world m -> the deepest penetrations and their sources (see the module doc)."""
    from trumans.contacts.rule import ContactScene, joint_contacts
    from trumans.skeleton import JOINT_NAMES

    r = joint_contacts(J, ContactScene(sc.scene, floor=False), floor=False)
    pen = np.asarray(r.penetration)
    phase = res.phase[0]
    kinds = np.array([res.phases[p].kind if p >= 0 else "-" for p in phase])
    by = defaultdict(float)
    for t, j in zip(*np.nonzero(pen > 0.03)):
        key = (JOINT_NAMES[j], r.names[r.object_index[t, j]] if r.object_index[t, j] >= 0 else "?", kinds[t])
        by[key] = max(by[key], float(pen[t, j]))
    worst = sorted(by.items(), key=lambda kv: -kv[1])[:top]
    t, j = np.unravel_index(int(np.argmax(pen)), pen.shape)
    return {"max_cm": round(float(pen.max()) * 100, 2), "at": {"frame": int(t), "joint": JOINT_NAMES[j],
            "object": r.names[r.object_index[t, j]] if r.object_index[t, j] >= 0 else "?", "phase": str(kinds[t]),
            "facing": bool(r.facing[t, j]), "signed_cm": round(float(r.distance[t, j]) * 100, 2)},
            "worst_over_3cm": [{"joint": k[0], "object": k[1], "phase": k[2], "cm": round(v * 100, 2)} for k, v in worst]}


def skate_report(J: np.ndarray, fps: float) -> dict:
    """Foot skate of the benchmark's definition broken down by run length and foot speed."""
    from trumans.intervals import run_bounds
    from trumans.eval.synthesis_metrics import _FEET
    from trumans.skeleton import FOOT_REST_HEIGHT as _FOOT_REST

    feet = J[:, _FEET]
    contact = (feet[..., 2] - _FOOT_REST) < 0.05
    step = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1)
    runs = []
    for f in range(len(_FEET)):
        s, e = run_bounds(contact[:, f])
        for a, b in zip(s, e):
            slide = step[a:b - 1, f].sum()
            runs.append((b - a, slide, slide / max(b - a - 1, 1) * fps))
    runs = np.array(runs) if runs else np.zeros((0, 3))
    out = {"runs": len(runs), "mean_cm": round(float(runs[:, 1].mean() * 100), 2) if len(runs) else 0.0}
    for name, sel in (("len<=3", runs[:, 0] <= 3), ("len 4-15", (runs[:, 0] > 3) & (runs[:, 0] <= 15)),
                      ("len>15", runs[:, 0] > 15), ("speed<0.2", runs[:, 2] < 0.2), ("speed>=0.2", runs[:, 2] >= 0.2)):
        out[name] = {"n": int(sel.sum()), "slide_cm_sum": round(float(runs[sel, 1].sum() * 100), 1)}
    out["longest_runs_frames"] = sorted(runs[:, 0].astype(int).tolist())[-5:]
    out["slide_sum_cm"] = round(float(runs[:, 1].sum() * 100), 1)
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("checkpoint", nargs="?", default=None)
    p.add_argument("--rooms", type=int, default=2)
    p.add_argument("--steps", type=int, default=SamplerConfig().steps, help="denoising steps (default: trumans sample's)")
    p.add_argument("--eta", type=float, default=SamplerConfig().eta)
    add_guidance_arguments(p)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--save", default=None)
    p.add_argument("--json", action="store_true")
    add_postprocess_arguments(p)
    args = p.parse_args()

    import torch

    from trumans.sample.cli import DEFAULT_CHECKPOINT
    from trumans.sample.eval_synthesis import EVAL_ROOM_SEEDS, eval_plan
    from trumans.sample.rollout import sample_plan, start_pose
    from trumans.sample.sampler import EpisodeSampler
    from trumans.sample.scene_input import load_sample_scene
    from trumans.eval.synthesis_metrics import motion_figures
    from trumans.model.checkpoint import load_checkpoint
    from trumans.skeleton import offsets_from_joints
    from trumans.synth.posture import seat_clearance

    ckpt = load_checkpoint(args.checkpoint or DEFAULT_CHECKPOINT, kind="generator")
    torch.set_grad_enabled(False)
    report, saved = [], {}
    for r, room_seed in enumerate(EVAL_ROOM_SEEDS[:args.rooms]):
        sc = load_sample_scene(f"room:{room_seed}")
        plan = eval_plan(sc, args.seed * 1000 + r)
        cfg = sampler_config(args)
        res = sample_plan(ckpt, EpisodeSampler(ckpt, sc.grids, cfg), sc.scene, sc.walkmap, plan, seed=args.seed + r)
        J = res.joints[0].astype(np.float64)
        old = motion_figures(res, sc, sit_offset=seat_clearance(offsets_from_joints(start_pose(ckpt)[None])))
        report.append({"room": room_seed, "figures": motion_figures(res, sc), "sit_offset_m": round(res.sit_offset, 4),
                       "seat_height_err_cm_vs_seat_clearance": old["seat_height_err_cm"],
                       "penetration": penetration_report(J, sc, res),
                       "skate": skate_report(J, res.fps)})
        saved[f"joints_{room_seed}"] = res.joints[0]
        saved[f"phase_{room_seed}"] = res.phase[0]
        saved[f"kinds_{room_seed}"] = np.array([ph.kind for ph in res.phases])
        saved[f"seams_{room_seed}"] = np.asarray(res.episode_starts)
    if args.save:
        np.savez(args.save, **saved)
    print(json.dumps(report) if args.json else json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
