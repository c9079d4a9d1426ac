"""`--shard K/N` on data synth / data import / augment and `trumans data merge` (issue 37 point 8): the
merge of all shards equals the unsharded build; bad shards and bad merges are refused before any work."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from trumans.cli import UsageError, console_main, main
from trumans.shards import SHARD_FILE, Shard, parse_shard

from helpers import CMU_WALK_BVH, TEST_DATA

SYNTH = ["--hours", "0.004", "--rooms", "3", "--seed", "4", "--workers", "1", "--real-share", "0", "--no-progress"]


def _files(root: Path) -> dict[str, bytes]:
    """Every sequence and scene file (relative path -> bytes)."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for d in ("sequences", "scenes")
            for p in sorted((root / d).rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """The unsharded 3-room build and its two shards (seconds: ~2 s a room)."""
    tmp = tmp_path_factory.mktemp("synth")
    assert main(["data", "synth", "--out", str(tmp / "full"), *SYNTH]) == 0
    for k in (1, 2):
        assert main(["data", "synth", "--out", str(tmp / f"s{k}"), *SYNTH, "--shard", f"{k}/2"]) == 0
    return tmp


def test_synth_shards_merge_to_the_unsharded_build(synth, tmp_path):
    s1, s2 = (json.loads((synth / f"s{k}" / SHARD_FILE).read_text()) for k in (1, 2))
    assert [e["id"] for e in s1["entries"]] == ["room_000", "room_002"] and [e["id"] for e in s2["entries"]] == ["room_001"]
    assert not (synth / "s1" / "index.json").exists()  # a shard is not a dataset on its own
    assert main(["data", "merge", str(tmp_path / "m"), str(synth / "s2"), str(synth / "s1"), "--no-progress"]) == 0
    full, merged = synth / "full", tmp_path / "m"
    assert (merged / "index.json").read_bytes() == (full / "index.json").read_bytes()  # splits, hash, config
    assert _files(merged) == _files(full)  # byte for byte
    assert sorted(p.name for p in (merged / "rooms").iterdir()) == ["room_000.json", "room_001.json", "room_002.json"]
    assert not (merged / SHARD_FILE).exists() and (merged / "summary.png").is_file()
    from trumans.dataset import Dataset

    assert len(Dataset(merged)) == 3


def test_merge_refuses_missing_duplicate_foreign_and_overlapping_shards(synth, tmp_path, capsys):
    s1, s2 = synth / "s1", synth / "s2"
    out = tmp_path / "m"

    def refused(*dirs, why):
        assert console_main(["data", "merge", str(out), *map(str, dirs)]) == 2
        err = capsys.readouterr().err
        assert why in err and err.count("\n") == 1, err
        assert not out.exists()  # nothing written

    refused(s1, why="1 of 2 shards missing: 2/2")
    refused(s1, s1, why="is given twice")
    dup = tmp_path / "dup"
    shutil.copytree(s1, dup)
    refused(s1, dup, why="shard 1/2 is given twice")
    refused(synth / "full", s1, why="holds a whole dataset, not a shard")
    unfinished = tmp_path / "unfinished"
    shutil.copytree(s2, unfinished)
    (unfinished / SHARD_FILE).unlink()
    refused(s1, unfinished, why="an unfinished shard")
    other = tmp_path / "other"  # the same shard of another seed
    shutil.copytree(s2, other)
    m = json.loads((other / SHARD_FILE).read_text())
    m["settings"]["seed"] = 5
    (other / SHARD_FILE).write_text(json.dumps(m))
    refused(s1, other, why="seed: 4 vs 5")
    overlap = tmp_path / "overlap"  # shard 2 claiming a file of shard 1
    shutil.copytree(s2, overlap)
    m = json.loads((overlap / SHARD_FILE).read_text())
    m["files"].append("sequences/room_000_t00.npz")
    shutil.copy(s1 / "sequences" / "room_000_t00.npz", overlap / "sequences")
    (overlap / SHARD_FILE).write_text(json.dumps(m))
    refused(s1, overlap, why="is in two shards")
    lost = tmp_path / "lost"
    shutil.copytree(s2, lost)
    (lost / "sequences" / "room_001_t00.npz").unlink()
    refused(s1, lost, why="but it is missing")


def test_merge_into_an_existing_dataset_needs_overwrite(synth, capsys):
    assert console_main(["data", "merge", str(synth / "full"), str(synth / "s1"), str(synth / "s2")]) == 2
    assert "--overwrite" in capsys.readouterr().err


@pytest.mark.parametrize("bad, why", [("0/3", "count from 1"), ("3/2", "more than N"), ("a/b", "is not a shard"),
                                      ("1/0", "N must be"), ("2", "is not a shard")])
def test_bad_shard_values_are_refused_at_the_command_line(bad, why, tmp_path, capsys):
    for cmd in (["data", "synth", "--out", str(tmp_path / "o")], ["augment", "--data", "d", "--out", str(tmp_path / "o")],
                ["data", "import", "x.bvh", "--input-format", "bvh", "--out", str(tmp_path / "o")]):
        with pytest.raises(UsageError, match=why):
            main([*cmd, "--shard", bad])
    assert console_main(["data", "synth", "--out", str(tmp_path / "o"), "--shard", bad]) == 2
    assert why in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_shard_selection_is_disjoint_and_complete():
    items = list(range(11))
    picked = [x for k in range(1, 5) for _, x in Shard(k, 4).pick(items)]
    assert sorted(picked) == items and parse_shard("2/4") == Shard(2, 4)


def test_an_empty_shard_is_refused_before_any_work(tmp_path, capsys):
    assert console_main(["data", "import", str(CMU_WALK_BVH), "--input-format", "bvh", "--out", str(tmp_path / "o"),
                         "--shard", "2/2"]) == 2
    assert "only 1 source files" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_import_shards_merge_to_the_unsharded_import(tmp_path):
    src = tmp_path / "mine"
    src.mkdir()
    for i, f in enumerate([CMU_WALK_BVH, TEST_DATA / "cmu_13_10_daz_first56.bvh", TEST_DATA / "cmu_13_10_daz_first56.bvh"]):
        shutil.copy(f, src / f"take{i}.bvh")
    files = sorted(str(p) for p in src.glob("*.bvh"))
    common = [*files, "--input-format", "bvh", "--fps", "30", "--feet-on-floor"]
    assert main(["data", "import", *common, "--out", str(tmp_path / "full")]) == 0
    for k in (1, 2):
        assert main(["data", "import", *common, "--out", str(tmp_path / f"s{k}"), "--shard", f"{k}/2"]) == 0
    assert main(["data", "merge", str(tmp_path / "m"), str(tmp_path / "s1"), str(tmp_path / "s2"), "--no-progress"]) == 0
    assert (tmp_path / "m" / "index.json").read_bytes() == (tmp_path / "full" / "index.json").read_bytes()
    assert _files(tmp_path / "m") == _files(tmp_path / "full")
    # the older spelling --format still works (hidden alias)
    assert main(["data", "import", files[0], "--format", "bvh", "--out", str(tmp_path / "old")]) == 0


def test_augment_shards_merge_to_the_unsharded_run(synth, tmp_path):
    common = ["--data", str(synth / "full"), "--splits", "train", "val", "test", "--variations", "1", "--kinds", "scale",
              "--workers", "1", "--no-progress"]
    assert main(["augment", *common, "--out", str(tmp_path / "full")]) == 0
    for k in (1, 2):
        assert main(["augment", *common, "--out", str(tmp_path / f"s{k}"), "--shard", f"{k}/2"]) == 0
    assert main(["data", "merge", str(tmp_path / "m"), str(tmp_path / "s1"), str(tmp_path / "s2"), "--no-progress"]) == 0
    assert (tmp_path / "m" / "index.json").read_bytes() == (tmp_path / "full" / "index.json").read_bytes()
    assert _files(tmp_path / "m") == _files(tmp_path / "full")
    full, merged = (json.loads((tmp_path / d / "manifest.json").read_text()) for d in ("full", "m"))
    assert merged["outputs"] == full["outputs"]
