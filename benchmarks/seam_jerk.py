"""The episode seams of the synthesis benchmark's plans: folded jerk, peak ratio, goal / seat errors.

    python benchmarks/seam_jerk.py [CHECKPOINT] [--rooms 3] [--seeds 0 1 2] [--json] [--save out.npz]
        [--seam-blend 3] [--no-foot-cleanup] ...   (the sampler switches of ``trumans eval synthesis``)

Runs the plans of ``trumans eval synthesis`` (same rooms, plan seeds, sampler) for every seed and
prints, per plan, ``seam_jerk_peak_ratio`` with its peak phase (0 = an episode's first new frame),
the folded jerk profile (m/s^3 per phase, ``trumans.eval.synthesis_metrics.folded_jerk``),
``transition_jerk_ratio``, goal and seat errors; then the means over the plans beside the real
corpus's ratio at the same fold. Switches off one cleanup step at a time (``--no-...``) to see
which one makes or hides the seam. ``--by-step`` also follows every episode through the cleanup
(``run_cleanup``'s observer): after the network and after each step, the mean joint jerk of the two
windows that straddle the seam (phases 0 and 1: context frames and the first new ones) over the
mean jerk of the windows inside the episode (phases 3..L-k-2), averaged over the episodes.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from trumans.sample.sampling_args import add_guidance_arguments, add_postprocess_arguments, sampler_config  # noqa: E402
from trumans.sample.sampler import SamplerConfig  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint", nargs="?", default=None)
    p.add_argument("--rooms", type=int, default=3)
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--steps", type=int, default=SamplerConfig().steps, help="denoising steps (default: trumans sample's)")
    p.add_argument("--eta", type=float, default=0.0)
    add_guidance_arguments(p)
    add_postprocess_arguments(p)
    p.add_argument("--save", default=None, help="write every plan's joints and seams (.npz)")
    p.add_argument("--by-step", action="store_true", help="seam jerk after the network and after each cleanup step")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()

    import torch

    from trumans.eval.synthesis_metrics import folded_jerk, motion_figures
    from trumans.model.checkpoint import load_checkpoint
    from trumans.sample.cli import DEFAULT_CHECKPOINT
    from trumans.sample.eval_synthesis import EVAL_ROOM_SEEDS, eval_plan
    from trumans.sample.rollout import sample_plan
    from trumans.sample.sampler import EpisodeSampler
    from trumans.sample.scene_input import load_sample_scene

    ckpt = load_checkpoint(args.checkpoint or DEFAULT_CHECKPOINT, kind="generator")
    config = sampler_config(args)
    torch.set_grad_enabled(False)
    stages: dict[str, list[float]] = {}
    if args.by_step:
        import trumans.sample.rollout as rollout

        original = rollout.run_cleanup

        def observed(episode, config, observe=None):
            def seam_ratio(J):  # (B, L, 24, 3), frames 0..k-1 the committed context
                jerk = np.linalg.norm(np.diff(J.astype(np.float64), n=3, axis=1), axis=-1).mean(-1)  # (B, L-3)
                k = episode.k  # window t covers frames t..t+3; phase of window t = t + 2 - k
                return float(jerk[:, k - 2:k].mean() / max(jerk[:, k + 1:-1].mean(), 1e-12))

            stages.setdefault("network", []).append(seam_ratio(episode.joints))

            def both(name, joints):
                stages.setdefault(name, []).append(seam_ratio(joints))
                if observe is not None:
                    observe(name, joints)
            return original(episode, config, observe=both)
        rollout.run_cleanup = observed
    rows, saved = [], {}
    for seed in args.seeds:
        for r, room_seed in enumerate(EVAL_ROOM_SEEDS[:args.rooms]):
            sc = load_sample_scene(f"room:{room_seed}")
            plan = eval_plan(sc, seed * 1000 + r)
            res = sample_plan(ckpt, EpisodeSampler(ckpt, sc.grids, config), sc.scene, sc.walkmap, plan, seed=seed + r)
            figs = motion_figures(res, sc)
            J = res.joints[0].astype(np.float64)
            cycle = res.episode_starts[1] - res.episode_starts[0]
            prof = folded_jerk(J, cycle, res.episode_starts[1] + res.context_frames) * res.fps ** 3
            rows.append({"seed": seed, "room": room_seed, "seconds": round(len(J) / res.fps, 1),
                         **{k: figs[k] for k in ("seam_jerk_peak_ratio", "seam_jerk_peak_phase", "transition_jerk_ratio",
                                                 "goal_err_cm", "seat_height_err_cm", "real_seam_jerk_peak_ratio")},
                         "folded_jerk_m_s3": [round(float(x), 2) for x in prof]})
            saved[f"joints_{seed}_{room_seed}"] = res.joints[0]
            saved[f"seams_{seed}_{room_seed}"] = np.asarray(res.episode_starts) + res.context_frames
            if not args.json:
                print(json.dumps(rows[-1]), flush=True)
    mean = {k: round(float(np.mean([x[k] for x in rows if x[k] is not None])), 3)
            for k in ("seam_jerk_peak_ratio", "transition_jerk_ratio", "goal_err_cm", "seat_height_err_cm")}
    mean["seam_jerk_peak_ratio_range"] = [min(x["seam_jerk_peak_ratio"] for x in rows),
                                          max(x["seam_jerk_peak_ratio"] for x in rows)]
    mean["real_seam_jerk_peak_ratio"] = rows[0]["real_seam_jerk_peak_ratio"]
    mean["plans"] = len(rows)
    if stages:
        mean["seam_over_inside_jerk_by_step"] = {k: round(float(np.mean(v)), 3) for k, v in stages.items()}
    if args.save:
        np.savez(args.save, **saved)
    print(json.dumps({"plans": rows, "mean": mean}) if args.json else json.dumps(mean))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
