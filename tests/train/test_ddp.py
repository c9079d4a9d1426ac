"""DDP: `torchrun --nproc_per_node 2 -m trumans.train` with gloo on CPU: the weights move, and the ranks agree."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from helpers import DATASET_VOCAB, REPO_ROOT, TINY_TOML, make_tiny_dataset
from trumans.model.checkpoint import load_checkpoint



def test_two_process_gloo_weights_identical(tmp_path: Path) -> None:
    torchrun = Path(sys.executable).parent / "torchrun"
    if not torchrun.exists():
        pytest.skip("torchrun is not installed next to the interpreter")
    data = make_tiny_dataset(tmp_path / "data", num_seqs=4, frames=120)
    cfg = tmp_path / "tiny.toml"
    cfg.write_text(TINY_TOML)
    # this checkout's code, not an installed copy (the subprocess starts outside the repository)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=os.pathsep.join([str(REPO_ROOT), os.environ.get("PYTHONPATH", "")]))
    cmd = [str(torchrun), "--standalone", "--nproc_per_node", "2", "-m", "trumans.train", "--config", str(cfg),
           "--data", str(data), "--out", str(tmp_path / "run"), "--steps", "4", "--seed", "3",
           "--device", "cpu", "--threads", "1", "--no-progress", "--json"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["world_size"] == 2 and res["steps"] == 4
    assert res["ranks_in_sync"] is True  # every rank's weight digest equals rank 0's (all_gather)
    ck = load_checkpoint(tmp_path / "run" / "checkpoint.pt")
    from trumans.train.config import load_config
    from trumans.train.tasks.generator import GeneratorTask
    from trumans.train.loop import initial_model, weights_digest

    model = ck.build_model(ema=False)
    assert weights_digest(model) == res["weights_sha256"]  # rank 0 saved the weights every rank holds
    # the weights moved away from the initialisation the loop starts from (seed 3): every parameter
    # that gets a gradient in every step changed (the null embeddings only when a condition is dropped)
    init = initial_model(GeneratorTask(load_config(cfg), vocabulary=DATASET_VOCAB), 3).state_dict()
    assert init.keys() == ck.model_state.keys()
    moved = {k: float((ck.model_state[k] - v).abs().max()) for k, v in init.items()}
    assert all(torch.isfinite(v).all() for v in ck.model_state.values())
    still = [k for k, d in moved.items() if d == 0.0 and not k.startswith("null_")]
    assert not still, still
    assert max(moved.values()) > 1e-3  # Adam at lr 1e-3 for 4 steps moves weights by ~1e-3 each step
