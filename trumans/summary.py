"""The ``--json`` summary line every command prints last: strict JSON, one line.

A figure that is not a finite number (NaN where nothing was measured, an infinite ratio) is
written as ``null``: ``json.dumps`` would write ``NaN`` / ``Infinity``, which JSON parsers refuse.
numpy scalars and arrays become plain numbers and lists.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["json_safe", "print_summary"]


def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None and numpy types made plain."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def print_summary(summary: dict) -> None:
    """Print ``summary`` as one line of strict JSON (non-finite figures as null) on stdout."""
    print(json.dumps(json_safe(summary), allow_nan=False, default=str), flush=True)
