"""Worker pools whose processes die with their parent (no orphan keeps writing after kill -9).

Each worker asks the kernel for SIGKILL when its parent dies (Linux ``prctl(PR_SET_PDEATHSIG)``)
and also runs a watchdog thread that exits when its parent pid changes (other systems, and the
window before the prctl call). Workers use one torch / BLAS thread (the machine is shared).
"""
from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
from typing import Literal

__all__ = ["worker_pool", "die_with_parent", "one_thread"]

_PR_SET_PDEATHSIG = 1


def one_thread() -> None:
    """One intra-op thread for torch / OpenMP in this process."""
    os.environ["OMP_NUM_THREADS"] = "1"
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)


def die_with_parent(parent_pid: int) -> None:
    """Make this process exit when ``parent_pid`` (its parent) dies."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the watchdog below still works
            pass
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)

    def watch() -> None:
        ev = threading.Event()
        while not ev.wait(0.5):
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, name="die-with-parent", daemon=True).start()


def _init(parent_pid: int) -> None:
    die_with_parent(parent_pid)
    one_thread()


def worker_pool(n: int, start: Literal["fork", "spawn"] = "spawn"):
    """A ``multiprocessing`` pool of ``n`` workers that die with this process (use with ``with``)."""
    if n < 1:
        raise ValueError(f"a pool needs >= 1 worker, got {n}")
    return mp.get_context(start).Pool(n, initializer=_init, initargs=(os.getpid(),))
