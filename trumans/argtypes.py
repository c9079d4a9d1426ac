"""argparse value types that refuse NaN, infinities and out-of-range numbers at the command line
(the message names the accepted range; ``trumans.cli`` prints it as one ``trumans: error:`` line)."""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["int_in", "float_in", "positive_int", "nonneg_int", "positive_float", "nonneg_float", "fraction", "seed"]


def int_in(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """An integer in [lo, hi] (either bound may be None)."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise argparse.ArgumentTypeError(f"{v} is out of range; give a whole number {_range(lo, hi)}")
        return v
    parse.__name__ = "int"
    return parse


def float_in(lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> Callable[[str], float]:
    """A finite number in [lo, hi] ((lo, hi] with ``lo_open``); NaN and inf are refused."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
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
