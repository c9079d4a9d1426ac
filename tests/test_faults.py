"""kill -9 of `trumans data synth` and `trumans augment` mid-run (issue 13): no worker is left
writing, the lock dies with the owner, and a rerun gives the result of an uninterrupted run."""
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from trumans.dataset import Dataset
from trumans.synth.build import SynthConfig, build_dataset

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


def _tagged(tag: str) -> list[int]:
    """pids of live processes whose environment carries ``TRUMANS_FAULT_TAG=tag``."""
    pids = []
    for p in Path("/proc").iterdir():
        if not p.name.isdigit():
            continue
        try:
            env = (p / "environ").read_bytes()
            state = (p / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if f"TRUMANS_FAULT_TAG={tag}".encode() in env.split(b"\0") and state != "Z":
            pids.append(int(p.name))
    return pids


def _kill_when(argv: list[str], ready, timeout: float = 120.0) -> str:
    """Start ``trumans argv``, kill -9 the parent as soon as ``ready()``, return its tag."""
    tag = uuid.uuid4().hex
    env = dict(os.environ, OMP_NUM_THREADS="1", TRUMANS_FAULT_TAG=tag)
    proc = subprocess.Popen([sys.executable, "-m", "trumans", *argv], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    t0, seen = time.time(), 0
    while not ready() and proc.poll() is None and time.time() - t0 < timeout:
        seen = max(seen, len(_tagged(tag)))
        time.sleep(0.02)
    seen = max(seen, len(_tagged(tag)))
    assert proc.poll() is None, "the run ended before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    assert seen >= 3, "no worker process was seen (the parent and two workers)"
    proc.wait()
    return tag


def _no_orphans(tag: str, out: Path) -> None:
    t0 = time.time()
    while _tagged(tag) and time.time() - t0 < 10:
        time.sleep(0.1)
    assert _tagged(tag) == [], "workers outlived their killed parent"
    snap = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    time.sleep(0.5)
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == snap, "something still writes"


@pytest.fixture(scope="module")
def clean_synth(tmp_path_factory):
    out = tmp_path_factory.mktemp("faults") / "clean"
    s = build_dataset(SynthConfig(out=str(out), hours=0.004, rooms=2, seed=4, workers=1), progress=False)
    return out, s


def test_kill_synth_then_resume(clean_synth, tmp_path):
    clean, s = clean_synth
    out = tmp_path / "killed"
    argv = ["data", "synth", "--out", str(out), "--hours", "0.004", "--rooms", "2", "--seed", "4", "--workers", "2"]
    tag = _kill_when(argv, lambda: (out / "scenes" / "room_000").is_dir() or (out / "scenes" / "room_001").is_dir())
    _no_orphans(tag, out)
    assert not (out / "index.json").exists()
    s2 = build_dataset(SynthConfig(out=str(out), hours=0.004, rooms=2, seed=4, workers=1), progress=False)
    assert s2["hash"] == s["hash"] and Dataset(out).hash == Dataset(clean).hash
    assert not list(out.rglob(".*.tmp"))


def test_kill_augment_then_resume(clean_synth, tmp_path):
    from augment.pipeline import PipelineConfig, augment_dataset

    src, _ = clean_synth
    cfg = dict(data=str(src), variations=1, workers=1, kinds=("move",), splits=("train", "val"))
    ref = augment_dataset(PipelineConfig(out=str(tmp_path / "ref"), **cfg), progress=False)
    assert ref["sources"] == 2
    out = tmp_path / "killed"
    argv = ["augment", "--data", str(src), "--out", str(out), "--variations", "1", "--kinds", "move",
            "--splits", "train", "val", "--workers", "2"]
    tag = _kill_when(argv, lambda: (out / "sequences").is_dir())
    _no_orphans(tag, out)
    again = augment_dataset(PipelineConfig(out=str(out), **cfg), progress=False)
    assert again["hash"] == ref["hash"] and again["outputs"] == ref["outputs"]
    assert not list(out.rglob(".*.tmp"))
