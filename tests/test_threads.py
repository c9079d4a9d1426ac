"""Torch threads of the inference commands: one flag, default 1, checked before any work."""
from __future__ import annotations

import subprocess
import sys

import pytest

from trumans.threads import INFERENCE_THREADS, set_threads


def test_set_threads_sets_and_refuses():
    code = ("import torch; from trumans.threads import set_threads; "
            "a = set_threads(1); b = set_threads(2); c = set_threads(0); print(a, b, c)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["1", "2", "2"]  # 0 leaves the count as it is
    for bad in (-1, 10 ** 6):
        with pytest.raises(ValueError, match="--threads"):
            set_threads(bad)


@pytest.mark.parametrize("cmd", [["sample", "--out", "x"], ["refine", "t.npz", "--out", "x"], ["eval", "synthesis"]])
def test_inference_commands_have_the_threads_flag_with_the_documented_default(cmd):
    from trumans.cli import build_parser

    args = build_parser(cmd).parse_args(cmd)
    assert args.threads == INFERENCE_THREADS == 1
    assert build_parser(["sample"]).parse_args(["sample", "--out", "x", "--threads", "2"]).threads == 2
