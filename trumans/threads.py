"""Torch CPU threads of a command: one flag, one default, one place that sets them.

Sampling and refining run small tensors (one body, 16-frame episodes) one network call after
another, where a second thread buys little and an oversubscribed machine makes torch's OpenMP
threads spin: on the 2-core reference machine under a load of ~15, one cpu-small guided episode
took 2.7-3.5 s with 1 thread and 66-67 s with 2; the paper config 1.3-1.8 s against 26-31 s
(side by side in one run; docs/results.md, "Threads"). So the inference commands default to **1**
thread; ``--threads N`` asks for more (worth it on an idle machine with large models), ``0`` keeps
torch's own default (the number of physical cores). Training keeps torch's default
(``trumans train --threads``) because its batches are large.
"""
from __future__ import annotations

import argparse

__all__ = ["INFERENCE_THREADS", "add_threads_argument", "set_threads"]

INFERENCE_THREADS = 1
MAX_THREADS = 1024


def add_threads_argument(p: argparse.ArgumentParser, default: int = INFERENCE_THREADS) -> None:
    """``--threads N`` (0 = torch's default) on an inference command."""
    p.add_argument("--threads", type=int, default=default, metavar="N",
                   help=f"torch CPU threads (default {default}: small sequential network calls gain little from more, "
                        "and a busy machine makes more threads crawl; 0 = torch's default, the physical cores)")


def set_threads(n: int | None) -> int:
    """Set torch's intra-op threads to ``n`` (None or 0: leave torch's default); returns the threads in use.
    Raises ValueError for a negative or absurd count."""
    import torch

    if n is not None:
        if not 0 <= int(n) <= MAX_THREADS:
            raise ValueError(f"--threads must be in [0, {MAX_THREADS}] (0 = torch's default), got {n}")
        if n:
            torch.set_num_threads(int(n))
    return torch.get_num_threads()
