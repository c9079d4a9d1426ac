"""Budgets on sizes derived from input, checked before anything is allocated.

A frame rate or a frame count read from a file or a flag decides how much memory resampling and
every later step allocate; these are the stated limits (a clear error names the value and the limit
instead of a multi-GiB allocation or a build that runs for days).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["MIN_FPS", "MAX_FPS", "MAX_FRAMES", "check_fps", "check_frames", "check_npy_size"]

MIN_FPS = 1.0  # Hz: slower is not motion capture (a BVH 'Frame Time: 1e6' is a broken file)
MAX_FPS = 1000.0  # Hz: faster than any capture system
MAX_FRAMES = 2_000_000  # frames of one sequence: 18.5 h at 30 fps, 10 GiB of float32 joints at most


def check_fps(fps: float, what: str = "fps") -> float:
    """``fps`` as a float, or ValueError naming ``what`` unless MIN_FPS <= fps <= MAX_FPS."""
    try:
        f = float(fps)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number of frames per second, got {fps!r}") from None
    if not (math.isfinite(f) and MIN_FPS <= f <= MAX_FPS):
        raise ValueError(f"{what} must be between {MIN_FPS:g} and {MAX_FPS:g} frames per second, got {fps!r}")
    return f


def check_frames(n: int | float, what: str = "the sequence") -> int:
    """``n`` as an int, or ValueError naming ``what`` unless 0 <= n <= MAX_FRAMES."""
    if not (math.isfinite(n) and 0 <= n <= MAX_FRAMES):
        raise ValueError(f"{what} would have {n:.4g} frames, more than the limit of {MAX_FRAMES:,} "
                         f"(trumans.limits.MAX_FRAMES); cut it into shorter clips")
    return int(n)


def check_npy_size(path: str | Path) -> None:
    """Refuse a ``.npy`` file whose header declares more data than the file holds (a 64-byte file can
    declare terabytes; ``np.load`` would try to allocate them), naming the declared and actual sizes.
    Reads only the header."""
    path = Path(path)
    with open(path, "rb") as f:
        try:
            version = np.lib.format.read_magic(f)
            read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _, dtype = read_header(f)
        except (ValueError, OSError, EOFError) as e:
            raise ValueError(f"{path} is not a readable .npy array ({e}); re-download or re-export it") from None
        data_bytes = path.stat().st_size - f.tell()
    if dtype.hasobject:
        raise ValueError(f"{path} holds Python objects; unpickling is refused (re-export it as a numeric array)")
    declared = int(np.prod(shape, dtype=np.float64) * dtype.itemsize)
    if declared > data_bytes:
        raise ValueError(f"{path} declares a {shape} {dtype} array ({declared / 2**30:.3g} GiB) but holds "
                         f"{data_bytes} bytes of data; the file is truncated or corrupt")
