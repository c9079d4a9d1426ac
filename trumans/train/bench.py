"""`python -m trumans.train.bench --config paper [--device cuda --precision bf16]`: time optimisation
steps of a config on random inputs.

No dataset needed: episodes, action labels and local grids are random tensors of the config's
shapes, so this measures the model + diffusion loss + Adam step alone (and proves it fits/runs). On a
GPU the inputs are made on the CPU and moved, as the trainer's batches are; the first step (kernel
selection) is left out of the timing when more than one step runs.
"""
from __future__ import annotations

import argparse
import time
from trumans.summary import print_summary
from trumans import argtypes

__all__ = ["bench_steps", "main"]


def bench_steps(config: str, steps: int = 1, batch_size: int | None = None, num_actions: int = 16, seed: int = 0,
                device: str = "cpu", precision: str = "fp32") -> dict:
    """Run ``steps`` Adam steps of the generator task with ``config`` on random data on ``device``
    (``precision`` 'bf16': the trainer's autocast of forward and loss); returns timing and size figures
    (``seconds_per_step``: the fastest timed step)."""
    import torch

    from trumans.train.tasks.generator import GeneratorTask
    from trumans.train.loop import initial_model

    task = GeneratorTask.from_config(config)
    task.vocabulary = [f"action{i}" for i in range(num_actions)]
    cfg = task.config
    B = batch_size or cfg.train.batch_size
    if precision not in ("fp32", "bf16"):
        raise ValueError(f"precision must be 'fp32' or 'bf16', got {precision!r}")
    dev = torch.device(device)
    model = initial_model(task, seed).to(dev).train()
    opt = torch.optim.Adam(model.parameters(), lr=cfg.train.lr)
    g = torch.Generator().manual_seed(seed)
    times, losses = [], []
    for _ in range(steps):
        batch = task.random_batch(B, g)
        t0 = time.perf_counter()
        with torch.autocast(dev.type, dtype=torch.bfloat16, enabled=precision == "bf16"):
            loss = task.loss(model, batch, g, dev).loss
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.train.grad_clip)
        opt.step()
        losses.append(loss.item())  # waits for the device
        times.append(time.perf_counter() - t0)
    timed = times[1:] if len(times) > 1 else times
    return {"config": cfg.name, "device": str(dev), "precision": precision, "batch_size": B, "steps": steps,
            "parameters": sum(p.numel() for p in model.parameters()),
            "seconds_per_step": min(timed), "median_seconds_per_step": float(sorted(timed)[len(timed) // 2]),
            "samples_per_s": B / min(timed), "loss": losses[-1], "finite": all(map(lambda v: v == v, losses))}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m trumans.train.bench", description=__doc__.splitlines()[0])
    p.add_argument("--config", default="paper")
    p.add_argument("--steps", type=int, default=1)
    p.add_argument("--batch-size", type=int, default=None)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--seed", type=argtypes.seed, default=0)
    p.add_argument("--device", default="cpu", help="torch device: cpu, cuda or cuda:N")
    p.add_argument("--precision", choices=("fp32", "bf16"), default="fp32")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    import torch

    torch.set_num_threads(a.threads)
    r = bench_steps(a.config, a.steps, a.batch_size, seed=a.seed, device=a.device, precision=a.precision)
    print(f"{r['config']} on {r['device']} ({r['precision']}): {r['parameters'] / 1e6:.2f} M parameters, batch {r['batch_size']}, "
          f"{r['seconds_per_step']:.3f} s/step ({r['samples_per_s']:.1f} samples/s), loss {r['loss']:.4f}")
    if a.json:
        print_summary(r)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
