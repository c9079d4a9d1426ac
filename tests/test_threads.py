"""Torch and BLAS threads of the inference commands: one flag, default 1, checked before any work."""
from __future__ import annotations

import subprocess
import sys

import pytest

from trumans.threads import INFERENCE_THREADS, set_blas_threads, set_threads


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


def test_set_threads_caps_the_blas_of_numpy_and_scipy():
    code = ("import ctypes, numpy, scipy.linalg\n"
            "from trumans.threads import set_threads, set_blas_threads\n"
            "def counts(libs):\n"
            "    out = []\n"
            "    for path in sorted({l.split()[-1] for l in open('/proc/self/maps') if 'openblas' in l.rsplit('/', 1)[-1].lower()}):\n"
            "        lib = ctypes.CDLL(path)\n"
            "        g = next(getattr(lib, n) for n in ('openblas_get_num_threads', 'openblas_get_num_threads64_',\n"
            "                 'scipy_openblas_get_num_threads', 'scipy_openblas_get_num_threads64_') if hasattr(lib, n))\n"
            "        out.append(g())\n"
            "    return out\n"
            "capped = set_blas_threads(1); a = counts(capped)\n"
            "set_threads(2); b = counts(capped)\n"
            "print(len(capped), a, b)\n")
    env = {k: v for k, v in __import__("os").environ.items() if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    n, rest = out.split(" ", 1)
    if int(n) == 0:
        pytest.skip("no OpenBLAS loaded here (another BLAS): nothing to cap")
    a, b = rest.strip().split("] [")
    assert set(a.strip("[]").split(", ")) == {"1"} and set(b.strip("[]").split(", ")) == {"2"}
    with pytest.raises(ValueError, match="BLAS threads"):
        set_blas_threads(0)
