"""argparse value types that refuse NaN, infinities and out-of-range numbers at the command line
(the message names the accepted range; ``trumans.cli`` prints it as one ``trumans: error:`` line)."""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["int_in", "float_in", "positive_int", "nonneg_int", "positive_float", "nonneg_float", "fraction", "seed", "device"]


def int_in(lo: int | None = None, hi: int | None = None, limit: str | None = None) -> Callable[[str], int]:
    """An integer in [lo, hi] (either bound may be None); ``limit``: the name of the size budget in
    ``trumans.limits`` that ``hi`` is, named when a value is above it."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if limit is not None and hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"{v:,} is more than the limit of {hi:,} (trumans.limits.{limit}); "
                                             f"give a whole number {_range(lo, hi)}")
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"{v} is out of range; give a whole number {_range(lo, hi)}")
        return v
    parse.__name__ = "int"
    return parse


def float_in(lo: float | None = None, hi: float | None = None, lo_open: bool = False,
             limit: str | None = None) -> Callable[[str], float]:
    """A finite number in [lo, hi] ((lo, hi] with ``lo_open``); NaN and inf are refused; ``limit`` as
    for ``int_in``."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if limit is not None and hi is not None and math.isfinite(v) and v > hi:
            raise argparse.ArgumentTypeError(f"{text} is more than the limit of {hi:,g} (trumans.limits.{limit}); "
                                             f"give a finite number {_range(lo, hi, lo_open)}")
        if not math.isfinite(v) or (lo is not None and (v <= lo if lo_open else v < lo)) \
                or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"{text} is out of range; give a finite number "
                                             f"{_range(lo, hi, lo_open)}")
        return v
    parse.__name__ = "float"
    return parse


def _range(lo, hi, lo_open: bool = False) -> str:
    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{lo}, {hi}]"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {lo}"
    return f"<= {hi}" if hi is not None else ""


positive_int = int_in(1)
nonneg_int = int_in(0)
positive_float = float_in(0.0, lo_open=True)
nonneg_float = float_in(0.0)
fraction = float_in(0.0, 1.0)
seed = int_in(0, 2**32 - 1)  # --seed: every random generator (numpy, torch) takes it whole


def device(text: str) -> str:
    """A torch device this machine has: ``cpu``, ``cuda`` or ``cuda:N`` (refused, naming the fix, when
    torch has no CUDA or no such GPU)."""
    import torch

    name = text.strip().lower()
    if name == "cpu":
        return name
    if name == "cuda" or (name.startswith("cuda:") and name[5:].isdigit()):
        if not torch.cuda.is_available():
            raise argparse.ArgumentTypeError(f"{text!r}: this machine's torch has no CUDA; use --device cpu")
        index = int(name[5:]) if ":" in name else 0
        if index >= torch.cuda.device_count():
            raise argparse.ArgumentTypeError(f"{text!r}: there are {torch.cuda.device_count()} CUDA devices; "
                                             f"choose cuda:0 .. cuda:{torch.cuda.device_count() - 1}")
        return name
    raise argparse.ArgumentTypeError(f"{text!r} is not a device; give cpu, cuda or cuda:N")
