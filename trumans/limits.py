"""Budgets on sizes derived from input, checked before anything is allocated.

A frame rate or a frame count read from a file or a flag decides how much memory resampling and
every later step allocate; a config's ``d_model`` / ``layers`` / ``ff``, its voxel ``grid`` and its
batch size decide how much a network and a training batch take; a room or case count decides how
long a build runs. These are the stated limits: a clear error names the value, the limit (by its
name here) and the fix, instead of a multi-GiB allocation or a build that runs for days. Each
budget is derived from bytes or hours, written beside it; raise the constant for a bigger machine.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

__all__ = ["MIN_FPS", "MAX_FPS", "MAX_FRAMES", "MAX_PARAMETERS", "MAX_GRID", "MAX_BATCH", "MAX_BATCH_BYTES",
           "MAX_ROOMS", "MAX_SYNTH_HOURS", "MAX_CASES", "MAX_EVAL_SEQUENCES", "MAX_SAMPLES", "MAX_VARIATIONS",
           "MAX_NESTING",           "check_fps", "check_frames", "check_npy_size", "transformer_parameters",
           "transformer_activation_bytes", "check_transformer", "check_grid", "check_batch", "check_count"]

MIN_FPS = 1.0  # Hz: slower is not motion capture (a BVH 'Frame Time: 1e6' is a broken file)
MAX_FPS = 1000.0  # Hz: faster than any capture system
MAX_FRAMES = 2_000_000  # frames of one sequence: 18.5 h at 30 fps, 10 GiB of float32 joints at most
# one network's transformer: 1e9 parameters = 4 GiB of float32 weights, 16 GiB while training (weights,
# gradients and Adam's two moments); the paper's denoiser has 17 M
MAX_PARAMETERS = 1_000_000_000
# voxels per side of the scene perceiver's local grid: 128**3 = 2.1 M voxels, 2 MiB per cached episode as
# bool and 8 MiB per batch sample as float32 (the default is 32)
MAX_GRID = 128
MAX_BATCH = 65_536  # samples in one training or validation batch, any task
# one generator batch: inputs plus the activations kept for the backward pass (transformer_activation_bytes);
# the paper's batch of 256 takes about 2.6 GiB
MAX_BATCH_BYTES = 64 * 2**30
# rooms of `data synth`: a room takes 2-3 s of one core and about 1 MB on disk; 10,000 rooms are 8 h
MAX_ROOMS = 10_000
MAX_SYNTH_HOURS = 10_000.0  # hours of synthetic motion: 1.1 G frames, about 100 GB of sequences
MAX_CASES = 1_000  # `eval augment --cases`: synthetic clips per contact kind (5 kinds, ~1 s of IK a clip)
MAX_EVAL_SEQUENCES = 100_000  # `eval augment --max-seqs`: sequences read and augmented by one evaluation
MAX_SAMPLES = 256  # bodies sampled in one batch (`sample --num-samples`), a few MB each per episode
MAX_VARIATIONS = 50  # augment: variations per touched object (the paper uses 2); each is a written sequence
MAX_NESTING = 100  # levels of nested arrays / objects in a JSON or TOML input (every trumans file nests < 10)


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


def _over(what: str, value: float, limit: float, name: str, fix: str) -> ValueError:
    return ValueError(f"{what} is {value:,}, more than the limit of {limit:,} (trumans.limits.{name}); {fix}")


def transformer_parameters(d_model: int, layers: int, ff: int) -> int:
    """Parameters of a stack of ``layers`` transformer encoder layers of width ``d_model`` and
    feed-forward width ``ff``: attention 4 d^2 + 4 d, feed-forward 2 d ff + ff + d, two layer norms 4 d."""
    d = int(d_model)
    return int(layers) * (4 * d * d + 2 * d * int(ff) + int(ff) + 9 * d)


def transformer_activation_bytes(tokens: int, d_model: int, layers: int, heads: int, ff: int) -> int:
    """Float32 bytes one sample's pass through such a stack keeps for the backward pass (an estimate:
    per layer and token about 10 d + 2 ff values, plus 2 heads x tokens attention weights)."""
    return 4 * int(layers) * int(tokens) * (10 * int(d_model) + 2 * int(ff) + 2 * int(heads) * int(tokens))


def check_transformer(d_model: int, layers: int, heads: int, ff: int, what: str = "the transformer") -> None:
    """ValueError unless d_model, layers, heads, ff >= 1, heads divides d_model and the stack has at
    most MAX_PARAMETERS parameters (``transformer_parameters``); checked before any weight exists."""
    for name, v in (("d_model", d_model), ("layers", layers), ("heads", heads), ("ff", ff)):
        if not isinstance(v, int) or isinstance(v, bool) or v < 1:
            raise ValueError(f"{what}: {name} must be a whole number >= 1, got {v!r}")
    if d_model % heads:
        raise ValueError(f"{what}: heads ({heads}) must divide d_model ({d_model}); e.g. heads = "
                         f"{max(h for h in (1, 2, 4, 8, 16) if d_model % h == 0)}")
    n = transformer_parameters(d_model, layers, ff)
    if n > MAX_PARAMETERS:
        raise ValueError(f"{what}: d_model {d_model}, layers {layers}, ff {ff} make {n:,} parameters, more than the "
                         f"limit of {MAX_PARAMETERS:,} (trumans.limits.MAX_PARAMETERS: 4 GiB of float32 weights); "
                         f"lower d_model, layers or ff")


def check_grid(grid: int, what: str = "grid") -> None:
    """ValueError unless 1 <= grid <= MAX_GRID voxels per side."""
    if not 1 <= grid <= MAX_GRID:
        raise ValueError(f"{what} must be 1..{MAX_GRID} voxels per side (trumans.limits.MAX_GRID: "
                         f"{MAX_GRID}**3 voxels, 8 MiB a sample), got {grid}; lower {what}")


def check_batch(batch_size: int, sample_bytes: int = 0, what: str = "batch_size") -> None:
    """ValueError unless 1 <= batch_size <= MAX_BATCH and batch_size x ``sample_bytes`` (one
    sample's inputs and kept activations, bytes; 0 = not known) <= MAX_BATCH_BYTES."""
    if batch_size < 1:
        raise ValueError(f"{what} must be >= 1, got {batch_size}")
    if batch_size > MAX_BATCH:
        raise _over(what, batch_size, MAX_BATCH, "MAX_BATCH", f"lower {what}")
    need = batch_size * sample_bytes
    if need > MAX_BATCH_BYTES:
        raise ValueError(f"{what} {batch_size:,} x {sample_bytes / 2**20:.3g} MiB a sample needs "
                         f"{need / 2**30:.3g} GiB, more than the limit of {MAX_BATCH_BYTES / 2**30:g} GiB "
                         f"(trumans.limits.MAX_BATCH_BYTES); lower {what} (or the model's or grid's size)")


def check_count(value: int, limit: int, name: str, what: str) -> int:
    """``value`` unless it is above ``limit`` (the constant ``name`` of this module): ValueError naming
    ``what`` (a flag or key), the value, the limit and the fix."""
    if value > limit:
        raise _over(what, value, limit, name, f"give {what} <= {limit:,}")
    return value

