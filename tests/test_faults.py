"""kill -9 of `trumans data synth` and `trumans augment` mid-run (issue 13): no worker is left
writing, the lock dies with the owner, and a rerun gives the result of an uninterrupted run."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trumans.dataset import Dataset
from trumans.synth.build import SynthConfig, build_dataset

from helpers import REPO_ROOT

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _session(sid: int) -> list[int]:
    """Live (not zombie) processes of session ``sid``: the killed run and every process it started."""
    pids = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            fields = (p / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[3]) == sid and fields[0] not in ("Z", "X"):  # fields: state ppid pgrp session ...
            pids.append(int(p.name))
    return pids


def _kill_when(argv: list[str], ready, timeout: float = 180.0) -> int:
    """Start ``trumans argv`` in its own session, kill -9 it (the parent only) as soon as ``ready()``;
    returns the session id."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-m", "trumans", *argv], cwd=REPO_ROOT, env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0, seen = time.time(), 0
    while not ready() and proc.poll() is None and time.time() - t0 < timeout:
        seen = max(seen, len(_session(proc.pid)))
        time.sleep(0.02)
    seen = max(seen, len(_session(proc.pid)))
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert seen >= 3, "no worker process was seen (the parent and two workers)"
    return proc.pid


def _no_orphans(sid: int, out: Path) -> None:
    """Every process of the killed run ends (a spawned worker still importing exits when its
    initializer finds its parent gone, before taking work) and none writes after the kill."""
    time.sleep(0.5)
    snap = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    t0 = time.time()
    while _session(sid) and time.time() - t0 < 120:
        time.sleep(0.2)
    assert _session(sid) == [], "workers outlived their killed parent"
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == snap, "an orphan wrote after the kill"


@pytest.fixture(scope="module")
def clean_synth(tmp_path_factory):
    out = tmp_path_factory.mktemp("faults") / "clean"
    s = build_dataset(SynthConfig(out=str(out), hours=0.004, rooms=2, seed=4, workers=1), progress=False)
    return out, s


def test_kill_synth_then_resume(clean_synth, tmp_path):
    clean, s = clean_synth
    out = tmp_path / "killed"
    argv = ["data", "synth", "--out", str(out), "--hours", "0.004", "--rooms", "2", "--seed", "4", "--workers", "2",
            "--real-share", "0"]
    sid = _kill_when(argv, lambda: (out / "scenes" / "room_000").is_dir() or (out / "scenes" / "room_001").is_dir())
    _no_orphans(sid, out)
    assert not (out / "index.json").exists()
    s2 = build_dataset(SynthConfig(out=str(out), hours=0.004, rooms=2, seed=4, workers=1), progress=False)
    assert s2["hash"] == s["hash"] and Dataset(out).hash == Dataset(clean).hash
    assert not list(out.rglob(".*.tmp"))


def test_kill_augment_then_resume(clean_synth, tmp_path):
    from trumans.augment.pipeline import PipelineConfig, augment_dataset

    src, _ = clean_synth
    cfg = dict(data=str(src), variations=1, workers=1, kinds=("move",), splits=("train", "val"))
    ref = augment_dataset(PipelineConfig(out=str(tmp_path / "ref"), **cfg), progress=False)
    assert ref["sources"] == 2
    out = tmp_path / "killed"
    argv = ["augment", "--data", str(src), "--out", str(out), "--variations", "1", "--kinds", "move",
            "--splits", "train", "val", "--workers", "2"]
    sid = _kill_when(argv, lambda: (out / "sequences").is_dir())
    _no_orphans(sid, out)
    again = augment_dataset(PipelineConfig(out=str(out), **cfg), progress=False)
    assert again["hash"] == ref["hash"] and again["outputs"] == ref["outputs"]
    assert not list(out.rglob(".*.tmp"))
