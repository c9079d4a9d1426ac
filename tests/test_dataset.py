"""Dataset folder reader (trumans.dataset): index round trip and bad inputs."""
from __future__ import annotations

import json

import numpy as np
import pytest

from trumans.scenes.occupancy import OccupancyGrid
from trumans.dataset import INDEX_FILE, Dataset, content_hash, write_index
from trumans.sequence import Sequence, save_sequence
from trumans.skeleton import REST_JOINTS


def _make(root, n_per_split=(2, 1, 1)):
    vocab = ["walk", "sit"]
    splits, scenes = {}, {}
    rng = np.random.default_rng(0)
    for s, n in zip(("train", "val", "test"), n_per_split):
        splits[s] = []
        for i in range(n):
            sid = f"{s}_room{i}"
            T = 5 + i
            seq = Sequence(joints=REST_JOINTS[None].repeat(T, 0) + rng.normal(0, 0.01, (T, 24, 3)), fps=30.0,
                           actions=np.ones((T, 2), np.float32), action_names=vocab, scene=sid)
            rel = f"sequences/{sid}.npz"
            save_sequence(seq, root / rel)
            splits[s].append(rel)
            occ = OccupancyGrid(np.eye(4, dtype=bool)[:, :, None].repeat(3, 2), np.zeros(3), 0.02)
            occ.save(root / "scenes" / sid / "occupancy.npz")
            scenes[sid] = f"scenes/{sid}"
    files = [p for v in splits.values() for p in v]
    index = {"name": "t", "version": "1", "seed": 0, "fps": 30, "vocabulary": vocab, "splits": splits,
             "scenes": scenes, "counts": {"sequences": len(files)}, "hash": content_hash(root, files)}
    write_index(root, index)
    return index


def test_round_trip(tmp_path):
    index = _make(tmp_path)
    ds = Dataset(tmp_path)
    assert ds.vocabulary == ["walk", "sit"] and ds.fps == 30.0 and ds.name == "t"
    assert len(ds) == 4 and ds.split_names == ["train", "val", "test"]
    assert [p.name for p in ds.split("train")] == ["train_room0.npz", "train_room1.npz"]
    seq = ds.load(1)
    assert seq.scene == "train_room1" and seq.num_frames == 6
    assert ds.load("sequences/val_room0.npz").scene == "val_room0"
    assert ds.load(ds.split("test")[0]).scene == "test_room0"
    occ = ds.occupancy("val_room0")
    assert occ.grid.shape == (4, 4, 3) and occ.grid[2, 2, 1] and not occ.grid[1, 2, 1]
    assert ds.scene_dir("test_room0") == tmp_path / "scenes" / "test_room0"
    assert ds.hash == index["hash"] == content_hash(tmp_path, [str(p.relative_to(tmp_path)) for p in ds.files])


def test_relative_root_loads_its_split_paths(tmp_path, monkeypatch):
    """A dataset opened by a relative path loads the paths its own ``split`` returns (was: the root joined twice)."""
    _make(tmp_path / "ds")
    monkeypatch.chdir(tmp_path)
    ds = Dataset("ds")
    assert all(p.is_absolute() for p in ds.split("train"))
    assert ds.load(ds.split("train")[1]).scene == "train_room1"
    assert ds.load("sequences/val_room0.npz").scene == "val_room0"


def test_hash_changes_with_content(tmp_path):
    index = _make(tmp_path)
    files = [p for v in index["splits"].values() for p in v]
    seq = Dataset(tmp_path).load(0)
    seq.joints[0, 0, 0] += 0.001
    save_sequence(seq, tmp_path / files[0])
    assert content_hash(tmp_path, files) != index["hash"]


def test_bad_inputs(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        Dataset(tmp_path / "nope")
    with pytest.raises(FileNotFoundError, match="index.json"):
        Dataset(tmp_path)
    (tmp_path / INDEX_FILE).write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        Dataset(tmp_path)
    (tmp_path / INDEX_FILE).write_text(json.dumps({"name": "x"}))
    with pytest.raises(ValueError, match="lacks"):
        Dataset(tmp_path)
    with pytest.raises(ValueError, match="index lacks"):
        write_index(tmp_path, {"name": "x"})
    _make(tmp_path)
    (tmp_path / "sequences" / "val_room0.npz").unlink()
    with pytest.raises(FileNotFoundError, match="val_room0.npz"):
        Dataset(tmp_path)


def test_bad_lookups(tmp_path):
    _make(tmp_path)
    ds = Dataset(tmp_path)
    with pytest.raises(ValueError, match="unknown split"):
        ds.split("dev")
    with pytest.raises(IndexError, match="out of range"):
        ds.load(10)
    with pytest.raises(ValueError, match="not in this dataset"):
        ds.scene_dir("nowhere")
    with pytest.raises(FileNotFoundError):
        ds.load("sequences/missing.npz")
