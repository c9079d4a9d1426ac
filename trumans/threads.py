"""Torch CPU threads of a command: one flag, one default, one place that sets them.

Sampling and refining run small tensors (one body, 16-frame episodes) one network call after
another, where a second thread buys little and an oversubscribed machine makes torch's OpenMP
threads spin: on the 2-core reference machine under a load of ~15, one cpu-small guided episode
took 2.7-3.5 s with 1 thread and 66-67 s with 2; the paper config 1.3-1.8 s against 26-31 s
(side by side in one run; docs/results.md, "Threads"). So the inference commands default to **1**
thread; ``--threads N`` asks for more (worth it on an idle machine with large models), ``0`` keeps
torch's own default (the number of physical cores). Training keeps torch's default
(``trumans train --threads``) because its batches are large.

The same count caps the OpenBLAS that numpy and scipy load (``set_blas_threads``): their small
solves spin the same way. On that machine under a load of ~3, the HOI filter's body-drift fit
(8 solves of ~128 x 128) took 0.02 s with one BLAS thread and 1.3 s with two (docs/results.md,
"≥ 5,000 frames/s").
"""
from __future__ import annotations

import argparse
import ctypes
import os

__all__ = ["INFERENCE_THREADS", "add_threads_argument", "set_threads", "set_blas_threads"]

INFERENCE_THREADS = 1
MAX_THREADS = 1024


def add_threads_argument(p: argparse.ArgumentParser, default: int = INFERENCE_THREADS) -> None:
    """``--threads N`` (0 = torch's default) on an inference command."""
    p.add_argument("--threads", type=int, default=default, metavar="N",
                   help=f"torch and BLAS CPU threads (default {default}: small sequential network calls and solves gain little from more, "
                        "and a busy machine makes more threads crawl; 0 = torch's default, the physical cores)")


def set_threads(n: int | None) -> int:
    """Set torch's intra-op threads and the OpenBLAS threads of numpy and scipy (``set_blas_threads``) to
    ``n`` (None or 0: leave both defaults); returns torch's threads in use. Raises ValueError for a
    negative or absurd count."""
    import torch

    if n is not None:
        if not 0 <= int(n) <= MAX_THREADS:
            raise ValueError(f"--threads must be in [0, {MAX_THREADS}] (0 = torch's default), got {n}")
        if n:
            torch.set_num_threads(int(n))
            set_blas_threads(int(n))
    return torch.get_num_threads()


# OpenBLAS's thread setter under the names its builds export (plain; numpy's and scipy's wheels)
_BLAS_SETTERS = ("openblas_set_num_threads", "openblas_set_num_threads64_", "scipy_openblas_set_num_threads",
                 "scipy_openblas_set_num_threads64_")


def set_blas_threads(n: int) -> list[str]:
    """Cap every OpenBLAS loaded in this process (numpy's, scipy's) at ``n`` threads; returns the file
    names of the libraries capped. Loaded libraries are read from ``/proc/self/maps`` (Linux; elsewhere,
    or with another BLAS, nothing is done: set ``OPENBLAS_NUM_THREADS`` before starting instead)."""
    if n < 1:
        raise ValueError(f"BLAS threads must be >= 1, got {n}")
    import numpy  # noqa: F401  (load numpy's and scipy's BLAS, so that they are capped too)
    import scipy.linalg  # noqa: F401

    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.rsplit("/", 1)[-1].lower()}
    except OSError:
        return []
    capped = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _BLAS_SETTERS:
            setter = getattr(lib, name, None)
            if setter is not None:
                setter.argtypes, setter.restype = [ctypes.c_int], None
                setter(int(n))
                capped.append(os.path.basename(path))
                break
    return capped
