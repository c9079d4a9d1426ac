"""The GPU path (issue 38.5): sampler, trainer (bf16 autocast) and refine on CUDA give what the CPU
gives. Marked ``gpu`` and skipped without a CUDA device; on a GPU machine run
``pytest -m gpu tests/gpu`` (``benchmarks/gpu_check.sh`` runs it with the GPU timings)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from trumans.paths import MODELS_DIR

pytestmark = [pytest.mark.gpu,
              pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device (pytest -m gpu on a GPU machine)")]


def _room() -> "SceneGrids":
    """A 3 m room (no open3d needed): the floor, and a 0.45-m block 0.8 m ahead of the start."""
    from trumans.scenes.occupancy import OccupancyGrid
    from trumans.scenes.scene_grids import SceneGrids

    v = 0.05
    grid = np.zeros((60, 60, 50), bool)
    grid[:, :, :4] = True  # z < 0
    grid[46:56, 25:35, 4:13] = True  # x 0.8-1.3 m, y -0.25-0.25 m, up to 0.45 m
    return SceneGrids(OccupancyGrid(grid, np.array([-1.5 + v / 2, -1.5 + v / 2, -0.2 + v / 2]), v))


def _episode(device: str, guidance: float, room: bool = False) -> np.ndarray:
    from trumans.model.checkpoint import load_checkpoint
    from trumans.sample.rollout import start_context
    from trumans.sample.sampler import EpisodeSampler, Goal, SamplerConfig

    ck = load_checkpoint(MODELS_DIR / "generator.pt", kind="generator")
    s = EpisodeSampler(ck, _room() if room else None, SamplerConfig(goal_guidance=guidance), device=device)
    ctx = start_context(ck, np.array([0.0, 0.0]), 0.0)
    labels = np.zeros((1, ck.L_epi, len(ck.vocabulary)), np.float32)
    labels[..., ck.vocabulary.index("walk")] = 1.0
    # with the room: a seated target on the last frames (the seat term) and the block (penetration, cleanup)
    seated = tuple((f, 0.55) for f in range(ck.L_epi - 3, ck.L_epi)) if room else ()
    goal = Goal((1.0, 0.2), heading=np.pi if room else None, pelvis_z=seated)
    return s.episode(ctx, labels, [goal], generator=torch.Generator().manual_seed(0))


@pytest.mark.parametrize("guidance,room", [(0.0, False), (45.0, False), (45.0, True)])
def test_sampler_episode_on_cuda_matches_cpu(guidance, room):
    torch.backends.cuda.matmul.allow_tf32 = False
    torch.backends.cudnn.allow_tf32 = False
    cpu, gpu = _episode("cpu", guidance, room), _episode("cuda", guidance, room)
    assert gpu.shape == cpu.shape and np.isfinite(gpu).all()
    assert np.abs(gpu - cpu).max() < 0.01  # m: the same noise (drawn on the CPU), float rounding apart


def test_generate_long_motion_on_cuda():
    pytest.importorskip("open3d", reason="the default scene's queries need open3d (pip install open3d)")
    from trumans.api import generate

    seq = generate(seed=0, device="cuda", max_seconds=20.0)
    assert seq.joints.ndim == 3 and seq.joints.shape[1:] == (24, 3) and np.isfinite(seq.joints).all()
    assert seq.joints.shape[0] >= 100


def test_train_bf16_on_cuda(tmp_path: Path):
    from helpers import TINY_TOML, make_tiny_dataset
    from trumans.train.config import GeneratorConfig, load_config
    from trumans.train.loop import train

    root = make_tiny_dataset(tmp_path / "data")
    (root / "tiny.toml").write_text(TINY_TOML)
    d = load_config(root / "tiny.toml").to_dict()
    d["train"]["precision"] = "bf16"
    res = train(GeneratorConfig.from_dict(d), root, tmp_path / "run", steps=4, seed=0, progress=False, device="cuda")
    assert res.steps == 4 and np.isfinite(res.train_loss) and np.isfinite(res.val_loss)


def test_refine_on_cuda_matches_cpu():
    from trumans.refine import frames_from_sequence
    from trumans.refine.pipeline import HOIFilter, RefineOptions
    from helpers import carried_box_clip

    torch.backends.cuda.matmul.allow_tf32 = False
    s = carried_box_clip(T=90, seed=0)
    f, _ = frames_from_sequence(s, "box_0")
    opts = RefineOptions()
    cpu = HOIFilter.load(None, device="cpu").refine_frames(f, 30.0, "box", opts)
    gpu = HOIFilter.load(None, device="cuda").refine_frames(f, 30.0, "box", opts)
    assert np.isfinite(gpu).all() and np.abs(gpu - cpu).max() < 0.01


def test_train_bench_on_cuda_in_bf16():
    from trumans.train.bench import bench_steps

    r = bench_steps("cpu-small", steps=3, batch_size=4, device="cuda", precision="bf16")
    assert r["device"].startswith("cuda") and r["finite"] and r["seconds_per_step"] > 0
