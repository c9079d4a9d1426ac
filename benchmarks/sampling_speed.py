"""Seconds per episode of the sampler for the cpu-small, paper and paper-authors configs, side by side.

    python benchmarks/sampling_speed.py --json                 # every config, this machine
    python benchmarks/sampling_speed.py --configs paper-authors --device cuda

Weights are random (speed does not depend on them). For each config: the naive sampler (all T
steps, ancestral, scene and action encoders recomputed at every step), the fast one (conditions
encoded once per episode, ``--steps``
respaced DDIM steps, no guidance), the **default** one (``SamplerConfig()``, what ``trumans sample``
runs: 10 steps, the last 5 guided by 2 backward passes each, action guidance 2) and the earlier
default, ``QUALITY_SCHEDULE`` (20 steps, every one guided by 3 backward passes); one episode of
batch 1 at a time, the median of ``--repeats`` episodes after a warm-up (half as many for the slow
samplers). The scene-dependent guidance terms (seat, penetration) need a scene and are not timed
here; ``trumans eval synthesis`` times the whole sampler in rooms.
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from trumans.sample.sampler import QUALITY_SCHEDULE, EpisodeSampler, Goal, SamplerConfig
from trumans.sample.rollout import start_context
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import FeatureLayout, Normalizer
from trumans.model.nets import Denoiser
from trumans.skeleton import REST_JOINTS
from trumans.train.config import load_config

VOCAB_SIZE = 24


def random_checkpoint(name: str) -> Checkpoint:
    cfg = load_config(name)
    mc = cfg.denoiser_config(VOCAB_SIZE)
    model = Denoiser(mc)
    F = FeatureLayout().dim
    return Checkpoint(kind="generator", model_config=mc,
                      diffusion_config=DiffusionConfig(steps=cfg.diffusion.steps, schedule="cosine", prediction="x0"),
                      model_state=model.state_dict(), normalizer=Normalizer(REST_JOINTS.reshape(-1), np.full(F, 0.3)),
                      vocabulary=[f"a{i}" for i in range(VOCAB_SIZE)], fps=cfg.data.fps, L_epi=cfg.data.episode_frames,
                      k=cfg.data.transition_frames, grid={"n": cfg.data.grid, "extent": list(cfg.data.extent)})


# the network alone, as the authors' sampler: no goal guidance, plain conditional (trumans sample's default
# is guided, with action guidance 2: docs/generate.md)
UNGUIDED = dict(goal_guidance=0.0, action_scale=1.0)


def time_episode(ck: Checkpoint, config: SamplerConfig, repeats: int, device: str) -> float:
    s = EpisodeSampler(ck, None, config, device=device)
    ctx = start_context(ck, np.array([0.0, 0.0]), 0.0)
    labels = np.ones((1, ck.L_epi, len(ck.vocabulary)), np.float32)
    times = []
    for i in range(repeats + 1):
        t0 = time.perf_counter()
        s.episode(ctx, labels, [Goal((1.0, 0.0))], generator=torch.Generator().manual_seed(i))
        if device.startswith("cuda"):
            torch.cuda.synchronize()
        times.append(time.perf_counter() - t0)
    return float(np.median(times[1:]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--configs", nargs="+", default=["cpu-small", "paper", "paper-authors"])
    p.add_argument("--steps", type=int, default=10, help="steps of the fast sampler")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--device", default="cpu")
    p.add_argument("--threads", type=int, default=None, help="torch threads (default: torch's)")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.threads:
        torch.set_num_threads(a.threads)
    out = {"device": a.device, "threads": torch.get_num_threads()}
    for name in a.configs:
        ck = random_checkpoint(name)
        T = ck.diffusion_config.steps
        naive = time_episode(ck, SamplerConfig(steps=T, eta=1.0, naive=True, **UNGUIDED), max(1, a.repeats // 2), a.device)
        fast = time_episode(ck, SamplerConfig(steps=a.steps, **UNGUIDED), a.repeats, a.device)
        full = time_episode(ck, SamplerConfig(steps=T, eta=1.0, **UNGUIDED), max(1, a.repeats // 2), a.device)
        default = time_episode(ck, SamplerConfig(), max(1, a.repeats // 2), a.device)
        seconds = (ck.L_epi - ck.k) / ck.fps  # new motion per episode
        row = {"params_M": round(sum(v.numel() for v in ck.model_state.values()) / 1e6, 2),
               "naive_s_per_episode": round(naive, 4), f"fast_{a.steps}_steps_s_per_episode": round(fast, 4),
               f"encoders_once_{T}_steps_s_per_episode": round(full, 4),
               "speedup_vs_naive": round(naive / fast, 1),
               "realtime_factor": round(seconds / fast, 1),
               "default_s_per_episode": round(default, 4), "default_realtime_factor": round(seconds / default, 2),
               "default_speedup_vs_naive": round(naive / default, 2)}
        quality = time_episode(ck, SamplerConfig(**QUALITY_SCHEDULE), max(1, a.repeats // 2), a.device)
        row.update({"quality_s_per_episode": round(quality, 4), "quality_realtime_factor": round(seconds / quality, 2),
                    "default_speedup_vs_quality": round(quality / default, 2)})
        out[name] = row
    print(json.dumps(out) if a.json else json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
