"""`python -m trumans.train.bench --config paper`: time optimisation steps of a config on random inputs.

No dataset needed: episodes, action labels and local grids are random tensors of the config's
shapes, so this measures the model + diffusion loss + Adam step alone (and proves it fits/runs).
"""
from __future__ import annotations

import argparse
import time
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["bench_steps", "main"]


def bench_steps(config: str, steps: int = 1, batch_size: int | None = None, num_actions: int = 16, seed: int = 0) -> dict:
    """Run ``steps`` Adam steps of the generator task with ``config`` on random data; returns timing and size figures."""
    import torch

    from trumans.train.tasks.generator import GeneratorTask
    from trumans.train.loop import initial_model

    task = GeneratorTask.from_config(config)
    task.vocabulary = [f"action{i}" for i in range(num_actions)]
    cfg = task.config
    B = batch_size or cfg.train.batch_size
    model = initial_model(task, seed).train()
    opt = torch.optim.Adam(model.parameters(), lr=cfg.train.lr)
    g = torch.Generator().manual_seed(seed)
    dev = torch.device("cpu")
    times, losses = [], []
    for _ in range(steps):
        batch = task.random_batch(B, g)
        t0 = time.perf_counter()
        loss = task.loss(model, batch, g, dev).loss
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.train.grad_clip)
        opt.step()
        times.append(time.perf_counter() - t0)
        losses.append(loss.item())
    return {"config": cfg.name, "batch_size": B, "steps": steps, "parameters": sum(p.numel() for p in model.parameters()),
            "seconds_per_step": min(times), "samples_per_s": B / min(times), "loss": losses[-1],
            "finite": all(map(lambda v: v == v, losses))}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m trumans.train.bench", description=__doc__.splitlines()[0])
    p.add_argument("--config", default="paper")
    p.add_argument("--steps", type=int, default=1)
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    import torch

    torch.set_num_threads(a.threads)
    r = bench_steps(a.config, a.steps, a.batch_size, seed=a.seed)
    print(f"{r['config']}: {r['parameters'] / 1e6:.2f} M parameters, batch {r['batch_size']}, "
          f"{r['seconds_per_step']:.3f} s/step ({r['samples_per_s']:.1f} samples/s), loss {r['loss']:.4f}")
    if a.json:
        print_summary(r)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
