"""Training: a tiny dataset built here, data pipeline, overfitting, resume == uninterrupted, CLI, eval."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from helpers import DATASET_VOCAB, TINY_TOML, make_tiny_dataset


def TINY_TOML_PATH(tmp: Path) -> Path:
    p = Path(tmp) / "tiny.toml"
    p.write_text(TINY_TOML)
    return p


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    torch.set_num_threads(1)
    root = make_tiny_dataset(tmp_path_factory.mktemp("data"))
    cfg_path = root / "tiny.toml"
    cfg_path.write_text(TINY_TOML)
    return root, cfg_path


def test_config_loading_and_errors(tmp_path: Path) -> None:
    from trumans.train.config import builtin_configs, load_config

    assert {"cpu-small", "paper"} <= set(builtin_configs())
    paper = load_config("paper")
    assert (paper.model.d_model, paper.model.layers, paper.model.heads) == (512, 8, 16)
    assert paper.diffusion.steps == 100 and paper.train.lr == 1e-4
    bad = tmp_path / "bad.toml"
    bad.write_text("[model]\nd_modle = 3\n")
    with pytest.raises(ValueError, match="unknown key"):
        load_config(bad)
    bad.write_text("[train]\nsteps = 'many'\n")
    with pytest.raises(ValueError, match="train.steps must be a whole number"):
        load_config(bad)
    with pytest.raises(FileNotFoundError, match="built-in"):
        load_config("no-such-config")
    good = tmp_path / "share.toml"
    good.write_text("[data]\naugmented_share = 0.25\n")
    assert load_config(good).data.augmented_share == 0.25 and paper.data.augmented_share is None
    bad.write_text("[data]\naugmented_share = 1.5\n")
    with pytest.raises(ValueError, match="augmented_share must be a fraction"):
        load_config(bad)
    bad.write_text("[data]\naugmented_share = 'half'\n")
    with pytest.raises(ValueError, match="data.augmented_share must be a finite number"):
        load_config(bad)


def test_episodes_from_dataset(tiny) -> None:
    from trumans.scenes.local_grid import local_grids
    from trumans.train.config import load_config
    from trumans.train.data import BatchStream, build_episodes, load_episodes
    from trumans.dataset import Dataset
    from trumans.model.episodes import Normalizer, canonical_frame
    from trumans.resample import resample_sequence

    root, cfg_path = tiny
    cfg = load_config(cfg_path)
    ds = Dataset(root)
    eps = build_episodes(ds, "train", cfg.data, DATASET_VOCAB)
    # 150 frames at 30 fps -> 50 frames at 10 fps -> starts 0, 3, ..., 33 = 12 episodes per sequence
    assert len(eps) == 4 * 12 and eps.features.shape == (48, 16, 72) and eps.actions.shape == (48, 16, 3)
    assert np.allclose(eps.features[:, 0, :2], 0, atol=1e-5)  # canonical: first pelvis at the origin
    seq = resample_sequence(ds.load(eps.files[1]), 10.0)
    k = int(np.flatnonzero(eps.sequence == 1)[2])
    win = seq.joints[eps.start[k]:eps.start[k] + 16]
    origin, yaw = canonical_frame(win)
    assert np.allclose(eps.origin[k], origin) and np.isclose(eps.yaw[k], yaw)
    goal = np.array([[*win[-1, 0, :2], 0.0]])
    ref = local_grids(ds.occupancy("room0"), goal, np.array([yaw]), n=32, extent=(1.2, 1.2, 1.2))
    assert np.array_equal(eps.unpack_grids(np.array([k])), ref)
    assert eps.actions.max() > 1.0  # progress indicator present
    # ablations
    nop = build_episodes(ds, "train", cfg.with_overrides(data={"progress_indicator": False}).data, DATASET_VOCAB)
    assert set(np.unique(nop.actions)) <= {0.0, 1.0} and np.array_equal(nop.actions > 0, eps.actions > 0)
    ds.index["augmented"] = [ds.index["splits"]["train"][0]]
    noaug = build_episodes(ds, "train", cfg.with_overrides(data={"augmented": False}).data, DATASET_VOCAB)
    assert len(noaug) == 3 * 12
    # cache: the second load reads the file written by the first
    cache = root / "cache-test"
    a = load_episodes(Dataset(root), "val", cfg.data, DATASET_VOCAB, cache)
    files = list(cache.iterdir())
    assert len(files) == 1
    b = load_episodes(Dataset(root), "val", cfg.data, DATASET_VOCAB, cache)
    assert np.array_equal(a.grids, b.grids) and np.array_equal(a.features, b.features)
    # batches: deterministic in (seed, step, rank); ranks disjoint; every episode once per epoch
    s = BatchStream(eps, Normalizer.fit(eps.features), 8, seed=5)
    assert np.array_equal(s.indices(3), BatchStream(eps, s.norm, 8, seed=5).indices(3))
    r0, r1 = s.indices(2, 0, 2), s.indices(2, 1, 2)
    assert len(r0) == 4 and not set(r0) & set(r1)
    epoch = np.concatenate([s.indices(i) for i in range(6)])
    assert sorted(epoch.tolist()) == list(range(48))
    b = s.batch(0)
    assert b.x.shape == (8, 16, 72) and b.scene.shape == (8, 32, 32, 32) and b.scene.dtype == torch.bool


def test_episode_grids_do_not_depend_on_how_many_scenes_are_held(tmp_path: Path, monkeypatch) -> None:
    """build_episodes keeps only a few scenes' grids at a time (a dataset of thousands of scenes held
    them all: 29 MB each); scenes that come back after being dropped give the same grids."""
    import shutil

    from trumans.dataset import Dataset
    from trumans.scenes.occupancy import OccupancyGrid
    from trumans.dataset import content_hash, write_index
    from trumans.sequence import load_sequence, save_sequence
    from trumans.train import data as train_data
    from trumans.train.config import load_config

    root = make_tiny_dataset(tmp_path / "d", num_seqs=6)
    index = json.loads((root / "index.json").read_text())
    for k, shift in ((1, 8), (2, 16)):  # two more rooms, the box moved along x
        d = root / "scenes" / f"room{k}"
        shutil.copytree(root / "scenes" / "room0", d)
        occ = OccupancyGrid.load(d / "occupancy.npz")
        OccupancyGrid(np.roll(occ.grid, shift, axis=0), occ.origin, occ.voxel).save(d / "occupancy.npz")
        index["scenes"][f"room{k}"] = f"scenes/room{k}"
    paths = index["splits"]["train"] + index["splits"]["val"]
    for i, rel in enumerate(index["splits"]["train"]):  # rooms 0 1 2 0: room0 comes back after two others
        seq = load_sequence(root / rel)
        seq.scene = f"room{[0, 1, 2, 0][i]}"
        save_sequence(seq, root / rel)
    index["hash"] = content_hash(root, paths)
    write_index(root, index)
    cfg = load_config(TINY_TOML_PATH(tmp_path)).data
    every = train_data.build_episodes(Dataset(root), "train", cfg, DATASET_VOCAB)
    monkeypatch.setattr(train_data, "_SCENES_HELD", 1)
    one = train_data.build_episodes(Dataset(root), "train", cfg, DATASET_VOCAB)
    assert np.array_equal(every.grids, one.grids) and np.array_equal(every.features, one.features)
    first, last = (every.unpack_grids(np.flatnonzero(every.sequence == s)[:1]) for s in (0, 1))
    assert not np.array_equal(first, last)  # the rooms differ, so the grids compared are not all alike


def test_recent_only_memo_keeps_the_most_recently_used_entries() -> None:
    from trumans.train.data import RecentOnly

    m = RecentOnly(2)
    m["a"], m["b"] = 1, 2
    assert m["a"] == 1  # a read counts as use: "b" is now the oldest
    m["c"] = 3
    assert list(m) == ["a", "c"] and "b" not in m


def test_pooled_batches_hold_each_pool_share_and_walk_each_pool_once_per_epoch(tiny) -> None:
    from trumans.train.config import load_config
    from trumans.train.data import BatchStream, build_episodes
    from trumans.dataset import Dataset
    from trumans.model.episodes import Normalizer

    root, cfg_path = tiny
    eps = build_episodes(Dataset(root), "train", load_config(cfg_path).data, DATASET_VOCAB)  # 48 episodes
    groups = (np.arange(48) >= 12).astype(np.int64)  # 12 "original", 36 "augmented"
    s = BatchStream(eps, Normalizer.fit(eps.features), 8, seed=3, groups=groups, shares=[0.75, 0.25])
    steps = [s.indices(i) for i in range(40)]
    drawn = np.concatenate(steps)
    assert all(len(b) == 8 for b in steps)
    assert np.mean(groups[drawn] == 1) == 0.25  # exact over whole steps: 8 x 0.25 = 2 per step
    first = drawn[groups[drawn] == 0][:12]  # pool 0's first epoch: each of its episodes once
    assert sorted(first.tolist()) == list(range(12))
    r0, r1 = s.indices(5, 0, 2), s.indices(5, 1, 2)
    assert np.array_equal(np.sort(np.concatenate([r0, r1])), np.sort(s.indices(5)))
    assert np.array_equal(s.indices(7), BatchStream(eps, s.norm, 8, seed=3, groups=groups, shares=[0.75, 0.25]).indices(7))
    odd = BatchStream(eps, s.norm, 8, seed=3, groups=groups, shares=[0.9, 0.1])  # 0.8 per step on average
    assert np.mean(groups[np.concatenate([odd.indices(i) for i in range(50)])] == 1) == 0.1
    with pytest.raises(ValueError, match="sum to 1"):
        BatchStream(eps, s.norm, 8, seed=3, groups=groups, shares=[0.5, 0.6])
    with pytest.raises(ValueError, match="no episodes"):
        BatchStream(eps, s.norm, 8, seed=3, groups=np.zeros(48, np.int64), shares=[0.5, 0.5])
    with pytest.raises(ValueError, match="both groups and shares"):
        BatchStream(eps, s.norm, 8, seed=3, groups=groups)


def test_resume_equals_uninterrupted_run(tiny, tmp_path: Path) -> None:
    from trumans.train.config import load_config
    from trumans.train.loop import train
    from trumans.model.checkpoint import load_checkpoint

    root, cfg_path = tiny
    cfg = load_config(cfg_path)
    full = train(cfg, root, tmp_path / "full", steps=6, seed=1, progress=False)
    part = train(cfg, root, tmp_path / "part", steps=3, seed=1, progress=False)
    assert part.steps == 3
    with pytest.raises(ValueError, match="--resume"):
        train(cfg, root, tmp_path / "part", steps=6, seed=1, progress=False)
    with pytest.raises(ValueError, match="seed"):
        train(cfg, root, tmp_path / "part", steps=6, seed=2, resume=True, progress=False)
    resumed = train(cfg, root, tmp_path / "part", steps=6, seed=1, resume=True, progress=False)
    assert resumed.steps == 6 and resumed.weights_sha256 == full.weights_sha256
    a, b = load_checkpoint(full.checkpoint), load_checkpoint(resumed.checkpoint)
    for k in a.model_state:
        assert torch.equal(a.model_state[k], b.model_state[k]), k
        assert torch.equal(a.ema_state[k], b.ema_state[k]), k
    assert a.train_state["history"]["train"] == b.train_state["history"]["train"]
    assert np.isclose(full.val_loss, resumed.val_loss)
    other = train(cfg, root, tmp_path / "other", steps=6, seed=2, progress=False)
    assert other.weights_sha256 != full.weights_sha256  # the seed matters
    assert (tmp_path / "full" / "loss.png").stat().st_size > 1000


def test_cli_train_json_and_eval(tiny, tmp_path: Path, capsys) -> None:
    from trumans.model.checkpoint import load_checkpoint
    from trumans.cli import console_main, main

    root, cfg_path = tiny
    out = tmp_path / "run"
    rc = main(["train", "--config", str(cfg_path), "--data", str(root), "--out", str(out), "--steps", "3",
               "--ablate", "scene", "--ablate", "progress", "--no-progress", "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in ("steps", "samples_per_s", "train_loss", "val_loss", "val_loss_zero_baseline"):
        assert key in res
    assert res["steps"] == 3 and res["samples_per_s"] > 0 and res["val_loss_zero_baseline"] > 0
    ck = load_checkpoint(out / "checkpoint.pt")
    assert ck.model_config.scene is None and ck.model_config.action is not None
    assert ck.extra["progress_indicator"] is False  # the sampler must build 0/1 labels for this model
    rc = main(["eval", "train", str(out / "checkpoint.pt"), "--json"])
    assert rc == 0
    ev = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert np.isclose(ev["val_loss"], res["val_loss"], rtol=1e-5) and ev["data_hash_match"] is True
    assert console_main(["eval", "train", str(tmp_path / "missing.pt")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("trumans: error: checkpoint") and "does not exist" in err and err.count("\n") == 1
    assert console_main(["train", "--config", "nope", "--data", str(root), "--out", str(out)]) == 2


def test_scene_grids_place_dynamic_objects_at_episode_start() -> None:
    import trimesh

    from trumans.scenes.local_grid import local_grids
    from trumans.scenes.occupancy import scene_occupancy
    from trumans.scenes.scene import Scene, SceneObject
    from trumans.scenes.scene_grids import SceneGrids

    wall = trimesh.creation.box((0.2, 3.0, 2.0), trimesh.transformations.translation_matrix([1.5, 0, 1.0]))
    pose = trimesh.transformations.translation_matrix([0.3, 0.0, 0.25])
    box = SceneObject("box_0", "box", trimesh.creation.box((0.3, 0.3, 0.5)), pose=pose, dof="free", dynamic=True)
    scene = Scene("s", static={"wall": wall}, objects={"box_0": box})
    occ = scene_occupancy(scene, None, voxel=0.04)
    sg = SceneGrids(occ, scene)
    c, yaw = np.array([[0.0, 0.0, 0.0]]), np.array([0.3])
    at_scene_pose = sg.query(c, yaw, n=16)
    ref = local_grids(occ, c, yaw, n=16)
    assert (at_scene_pose == ref).mean() > 0.97 and at_scene_pose.sum() > 0.8 * ref.sum()
    empty = local_grids(sg.static, c, yaw, n=16)
    assert empty.sum() < ref.sum()  # the static grid lacks the box
    away = sg.query(c, yaw, {"box_0": trimesh.transformations.translation_matrix([5.0, 5.0, 0.25])[None]}, n=16)
    assert np.array_equal(away, empty)
    moved = trimesh.transformations.translation_matrix([-0.3, 0.2, 0.25])[None]
    g = sg.query(c, np.array([0.0]), {"box_0": moved}, n=16)
    # with yaw 0 the cell (i, j, k) centre is (-0.6 + (i + .5) 0.075, -0.6 + (j + .5) 0.075, (k + .5) 0.075)
    assert g[0, 4, 10, 3] and not g[0, 12, 10, 3]  # box centre (-0.3, 0.2) occupied; (0.3, 0.2) free
    with pytest.raises(ValueError, match="no dynamic object"):
        sg.query(c, yaw, {"chair_9": moved})


def test_augmented_data_joins_train_split_and_ablation_drops_it(tiny, tmp_path: Path) -> None:
    from trumans.train.config import load_config
    from trumans.train.loop import train
    from trumans.model.checkpoint import load_checkpoint

    root, cfg_path = tiny
    aug = make_tiny_dataset(tmp_path / "aug", num_seqs=3, seed=7)  # train split: 2 sequences x 12 episodes
    cfg = load_config(cfg_path)
    with_aug = train(cfg, root, tmp_path / "a", steps=1, progress=False, augmented_dirs=[aug])
    assert with_aug.train_episodes == 48 + 24 and with_aug.val_episodes == 24
    rec = load_checkpoint(with_aug.checkpoint).data
    assert rec["augmented"][0]["hash"] and rec["hash"]
    no_aug = train(cfg.with_overrides(data={"augmented": False}), root, tmp_path / "b", steps=1, progress=False,
                   augmented_dirs=[aug])
    assert no_aug.train_episodes == 48
    shared = train(cfg.with_overrides(data={"augmented_share": 0.5}), root, tmp_path / "c", steps=1, progress=False,
                   augmented_dirs=[aug])
    assert shared.train_episodes == 72
    with pytest.raises(ValueError, match="another config|config"):  # the share is part of the run's config
        train(cfg, root, tmp_path / "c", steps=2, resume=True, progress=False, augmented_dirs=[aug])
    with pytest.raises(ValueError, match="other data"):
        train(cfg, root, tmp_path / "a", steps=2, resume=True, progress=False)  # resumed without --augmented
    # fine-tuning (--init) may train on other data: the init's weights and normalisation start the run
    ft = train(cfg, aug, tmp_path / "ft", steps=0, progress=False, init=with_aug.checkpoint)
    start, tuned = load_checkpoint(with_aug.checkpoint), load_checkpoint(ft.checkpoint)
    np.testing.assert_array_equal(tuned.normalizer.mean, start.normalizer.mean)
    for k, v in start.ema_state.items():
        torch.testing.assert_close(tuned.model_state[k], v)
    assert tuned.data["hash"] != start.data["hash"] and tuned.meta["init"] == str(with_aug.checkpoint)


def test_run_folder_has_one_writer_and_sweeps_killed_temp_files(tiny, tmp_path: Path) -> None:
    from trumans.train.config import load_config
    from trumans.train.loop import train
    from trumans.io_lock import FolderLock, FolderLocked

    root, cfg_path = tiny
    cfg = load_config(cfg_path)
    run = tmp_path / "run"
    run.mkdir()
    stale = run / ".checkpoint.pt.abc123.tmp"  # what a kill -9 during a checkpoint write leaves
    stale.write_bytes(b"partial")
    train(cfg, root, run, steps=1, seed=1, progress=False)
    assert not stale.exists() and (run / "checkpoint.pt").is_file()
    with FolderLock(run, "another trainer"):
        with pytest.raises(FolderLocked, match="another trainer"):
            train(cfg, root, run, steps=2, seed=1, resume=True, progress=False)


def test_seam_loss_analytic_cases() -> None:
    from trumans.train.tasks.generator import seam_loss

    B, L, F, k = 3, 8, 5, 2
    x0 = torch.randn(B, L, F, generator=torch.Generator().manual_seed(0))
    mask = torch.zeros(B, L, F, dtype=torch.bool)
    mask[:2, :k] = True  # samples 0, 1 continue a context; sample 2 starts from nothing
    assert seam_loss(x0, x0, mask, k).item() == 0.0
    jumped = x0.clone()
    jumped[:, k:] += 0.5  # every new frame moved by 0.5: one step of 0.5 across the seam
    # over frames 0..4: 1st differences, one of 4 off by 0.5; 2nd, two of 3 by +-0.5; 3rd, the two by
    # 0.5 - 3 * 0.5 = -1 and 3 * 0.5 - 3 * 0.5 + 0.5 = 0.5
    expected = 0.5 / 4 + 2 * 0.5 / 3 + (1.0 + 0.5) / 2
    torch.testing.assert_close(seam_loss(jumped, x0, mask, k), torch.tensor(expected))
    later = x0.clone()
    later[:, k + 3:] += 0.5  # a jump after the seam window is not the seam term's business
    assert seam_loss(later, x0, mask, k).item() == 0.0
    only_free = x0.clone()
    only_free[2] += 1.0  # the sample without a context does not count
    assert seam_loss(only_free, x0, mask, k).item() == 0.0
    with pytest.raises(ValueError, match="one shape"):
        seam_loss(x0[:, :4], x0, mask, k)


def test_seam_weight_adds_the_term_and_zero_leaves_the_loss_alone(tiny) -> None:
    from trumans.train.tasks.generator import GeneratorTask
    from trumans.train.config import load_config

    root, cfg_path = tiny
    cfg = load_config(cfg_path)
    with pytest.raises(ValueError, match="seam_weight must be >= 0"):
        cfg.with_overrides(train={"seam_weight": -1.0})
    losses = {}
    for w in (0.0, 2.0):
        task = GeneratorTask(cfg.with_overrides(train={"seam_weight": w}))
        task.setup(root, root.parent / f"out_{w}", is_main=True, barrier=lambda: None, prev=None, progress=False)
        torch.manual_seed(0)
        model = task.build_model()
        out = task.loss(model, task.batch(0, 0, 1), torch.Generator().manual_seed(1), torch.device("cpu"))
        losses[w] = out
    assert "seam" not in losses[0.0].terms and "seam" in losses[2.0].terms
    torch.testing.assert_close(losses[2.0].terms["simple"], losses[0.0].terms["simple"])
    torch.testing.assert_close(losses[2.0].loss, losses[0.0].loss + 2.0 * losses[2.0].terms["seam"])
    assert losses[2.0].terms["seam"].item() > 0


def test_bf16_mixed_precision_trains_with_float32_weights(tiny, tmp_path: Path) -> None:
    """train.precision = "bf16": forward and loss under autocast (CPU here, CUDA on a GPU), weights and
    checkpoint float32, losses finite and different from the float32 run's; a bad value is refused."""
    from trumans.train.config import GeneratorConfig, load_config
    from trumans.train.loop import train
    from trumans.model.checkpoint import load_checkpoint

    root, cfg_path = tiny
    cfg = load_config(cfg_path)
    d = cfg.to_dict()
    d["train"]["precision"] = "bf16"
    half = GeneratorConfig.from_dict(d)
    full = train(cfg, root, tmp_path / "fp32", steps=3, seed=1, progress=False)
    mixed = train(half, root, tmp_path / "bf16", steps=3, seed=1, progress=False)
    assert np.isfinite(mixed.train_loss) and np.isfinite(mixed.val_loss)
    ck = load_checkpoint(mixed.checkpoint)
    assert all(v.dtype == torch.float32 for v in ck.model_state.values() if v.is_floating_point())
    assert mixed.weights_sha256 != full.weights_sha256  # autocast did run: bf16 rounding changed the steps
    assert abs(mixed.train_loss - full.train_loss) < 0.1 * abs(full.train_loss) + 1e-3
    d["train"]["precision"] = "fp16"
    with pytest.raises(ValueError, match="precision"):
        GeneratorConfig.from_dict(d)
