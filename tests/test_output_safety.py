"""Nothing outside --out is touched: empty or current-folder outputs are refused, --overwrite never
deletes a folder of the user's own files, and links inside an output are never followed to delete."""
import os
from pathlib import Path

import pytest
import trimesh

from trumans.dataset import DatasetWriter
from trumans.scenes.io import save_scene
from trumans.scenes.scene import Scene


def _user_files(root: Path) -> dict[str, str]:
    (root / "scenes").mkdir(parents=True)
    (root / "sequences").mkdir()
    (root / "scenes" / "kitchen.blend").write_text("my scene")
    (root / "sequences" / "notes.txt").write_text("my notes")
    return {str(p.relative_to(root)): p.read_text() for p in root.rglob("*") if p.is_file()}


def test_empty_and_current_folder_outputs_are_refused(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = _user_files(tmp_path)
    for out in ("", "  ", ".", str(tmp_path), ".."):
        with pytest.raises(ValueError, match="--out"):
            DatasetWriter(out, "data synth", {}, overwrite=True)
    assert {str(p.relative_to(tmp_path)): p.read_text() for p in tmp_path.rglob("*") if p.is_file()} == before


def test_overwrite_never_deletes_a_folder_of_the_users_files(tmp_path):
    out = tmp_path / "mine"
    before = _user_files(out)
    with pytest.raises(FileExistsError, match="holds no trumans output; choose another --out"):
        with DatasetWriter(out, "data synth", {"seed": 0}, overwrite=True):
            pass
    after = {str(p.relative_to(out)): p.read_text() for p in out.rglob("*") if p.is_file()}
    assert after == before


def test_overwrite_replaces_a_trumans_output_but_not_what_its_links_point_to(tmp_path):
    out, elsewhere = tmp_path / "ds", tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("keep")
    (elsewhere / "a.npz").write_text("theirs")
    with DatasetWriter(out, "data synth", {"seed": 0}) as w:
        (out / "sequences").mkdir()
        w.record("sequences/a.npz", "scenes/a.npz")
        (out / "sequences" / "a.npz").write_text("x")
        os.symlink(elsewhere, out / "scenes")  # a listed path reached through a link is not followed
    with DatasetWriter(out, "data synth", {"seed": 1}, overwrite=True) as w:  # other settings: replaced
        assert w.removed == 3  # sequences/a.npz, the claim and the output manifest
    assert not (out / "sequences").exists() and (out / "scenes").is_symlink()
    assert (elsewhere / "keep.txt").read_text() == "keep" and (elsewhere / "a.npz").read_text() == "theirs"


def test_resaving_a_scene_through_a_link_keeps_the_links_target(tmp_path):
    target = tmp_path / "theirs"
    scene = Scene(name="box", static={"floor": trimesh.creation.box((2.0, 2.0, 0.1))})
    save_scene(scene, target)
    (target / "their_notes.txt").write_text("keep")
    link = tmp_path / "out" / "scenes" / "box"
    link.parent.mkdir(parents=True)
    os.symlink(target, link)
    save_scene(scene, link)  # the link is replaced by a real folder; the target is left as it was
    assert not link.is_symlink() and (link / "scene.json").is_file()
    assert (target / "their_notes.txt").read_text() == "keep" and (target / "scene.json").is_file()


# ---- --overwrite through the real command line: only the files the output manifest lists go --------------------

def _cli(*argv) -> int:
    from trumans.cli import console_main

    return console_main([str(a) for a in argv])


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and not p.is_symlink()}


def _plant_user_files(out: Path, elsewhere: Path) -> None:
    """A note of the user's inside sequences/, and a link inside scenes/ to a folder of theirs."""
    elsewhere.mkdir(exist_ok=True)
    (elsewhere / "scene.json").write_text("their scene")
    (out / "sequences" / "my_notes.txt").write_text("keep me")
    os.symlink(elsewhere, out / "scenes" / "their_room")


def _user_files_survived(out: Path, elsewhere: Path) -> None:
    assert (out / "sequences" / "my_notes.txt").read_text() == "keep me"
    assert (out / "scenes" / "their_room").is_symlink()
    assert (elsewhere / "scene.json").read_text() == "their scene"


def _listed_is_complete(out: Path) -> None:
    """Every file the run wrote is in its output manifest (so --overwrite can remove it)."""
    from trumans.dataset import listed_outputs
    from trumans.io_lock import LOCK_FILE

    assert _tree(out) - {"sequences/my_notes.txt", LOCK_FILE} <= set(listed_outputs(out))


@pytest.fixture(scope="module")
def synth_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("ow") / "synth"
    assert _cli("data", "synth", "--out", out, "--hours", "0.002", "--rooms", "1", "--seed", "2", "--workers", "1",
                "--real-share", "0") == 0
    return out


def test_synth_overwrite_keeps_the_users_files_and_replaces_the_outputs(synth_out, tmp_path):
    import json
    import shutil

    from trumans.dataset import Dataset

    out = Path(shutil.copytree(synth_out, tmp_path / "synth", symlinks=True))
    _listed_is_complete(out)
    _plant_user_files(out, tmp_path / "theirs")
    assert _cli("data", "synth", "--out", out, "--hours", "0.002", "--rooms", "1", "--seed", "3", "--workers", "1",
                "--real-share", "0", "--overwrite") == 0
    _user_files_survived(out, tmp_path / "theirs")
    ds = Dataset(out)
    assert ds.index["seed"] == 3 and json.loads((out / "summary.json").read_text())["hash"] == ds.hash
    _listed_is_complete(out)


def test_augment_overwrite_keeps_the_users_files_and_a_linked_scene(synth_out, tmp_path):
    """Also the issue's case: OUT/scenes/<x> replaced by a link to a scene folder elsewhere is not
    emptied by an --overwrite run that writes that scene again (the link goes, its target stays)."""
    import json

    from trumans.dataset import Dataset

    out = tmp_path / "aug"
    args = ["augment", "--data", synth_out, "--out", out, "--workers", "1", "--variations", "1"]
    assert _cli(*args) == 0
    _listed_is_complete(out)
    _plant_user_files(out, tmp_path / "theirs")
    sid = json.loads((out / "manifest.json").read_text())["outputs"][0]["scene"]
    linked = tmp_path / "linked_scene"
    (out / "scenes" / sid).rename(linked)
    (linked / "my_edit.txt").write_text("mine")
    os.symlink(linked, out / "scenes" / sid)
    before = {p: (linked / p).read_bytes() for p in _tree(linked)}
    assert _cli(*args, "--seed", "1", "--overwrite") == 0
    _user_files_survived(out, tmp_path / "theirs")
    assert {p: (linked / p).read_bytes() for p in _tree(linked)} == before
    ds = Dataset(out)
    assert ds.index["seed"] == 1 and len(ds) >= 1
    _listed_is_complete(out)


def test_import_overwrite_keeps_the_users_files(tmp_path):
    from helpers import CMU_WALK_BVH

    from trumans.dataset import Dataset

    out = tmp_path / "imp"
    assert _cli("data", "import", CMU_WALK_BVH, "--format", "bvh", "--out", out) == 0
    _listed_is_complete(out)
    (out / "scenes").mkdir()  # a BVH import has no scenes: the user made this folder
    _plant_user_files(out, tmp_path / "theirs")
    assert _cli("data", "import", CMU_WALK_BVH, "--format", "bvh", "--out", out, "--seed", "5", "--overwrite") == 0
    _user_files_survived(out, tmp_path / "theirs")
    assert Dataset(out).index["seed"] == 5


def test_overwrite_of_an_output_without_manifest_derives_it_from_the_index(synth_out, tmp_path):
    """An output written before the output manifest existed (or a dataset with only an index.json):
    the files its index, scene.json files and records list are removed, nothing else."""
    import shutil

    from trumans.dataset import CLAIM_FILE, OUTPUTS_FILE, DatasetWriter

    out = Path(shutil.copytree(synth_out, tmp_path / "old", symlinks=True))
    listed = _tree(out)
    (out / OUTPUTS_FILE).unlink()
    (out / CLAIM_FILE).unlink()  # a dataset of another tool's making: only index.json says what it is
    _plant_user_files(out, tmp_path / "theirs")
    (out / "rooms" / "my_plan.json").write_text("{}")
    with DatasetWriter(out, "data synth", {"seed": 9}, overwrite=True) as w:
        assert w.removed == len(listed) - 2  # all but the manifest and claim deleted above
    _user_files_survived(out, tmp_path / "theirs")
    assert _tree(out) == {"sequences/my_notes.txt", "rooms/my_plan.json", CLAIM_FILE}


def test_a_tampered_output_manifest_cannot_reach_outside(tmp_path):
    from trumans.dataset import OUTPUTS_FILE, DatasetWriter

    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    out = tmp_path / "ds"
    with DatasetWriter(out, "data synth", {"seed": 0}):
        pass
    with open(out / OUTPUTS_FILE, "a") as f:
        f.write(f"../outside.txt\n{outside}\n./../outside.txt\n\n")
    with DatasetWriter(out, "data synth", {"seed": 1}, overwrite=True):
        pass
    assert outside.read_text() == "keep"
    with pytest.raises(ValueError, match="not a relative path inside"):
        DatasetWriter(out, "data synth", {"seed": 1}).record("../x")


# ---- single-file and run-folder outputs: refused before any work ------------------------------------------------

def _one_line_refusal(capsys, argv, *must) -> str:
    rc = _cli(*argv)
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err and "this is a bug" not in err, (rc, err)
    for m in must:
        assert m in lines[0], (m, lines[0])
    return lines[0]


def _bytes(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_outputs_never_replace_a_file_of_a_dataset(synth_out, capsys):
    """`sample --out DS/sequences/<stem>` (and refine/track onto a dataset sequence) would silently
    change that dataset: refused before sampling, the dataset byte-identical."""
    seq = next((synth_out / "sequences").glob("*.npz"))
    scene = next((synth_out / "scenes").iterdir())
    before = _bytes(synth_out)
    for argv in (["sample", "--out", seq.with_suffix(""), "--goto", "1,1"],
                 ["refine", seq, "--out", seq],
                 ["track", seq, "--scene", scene, "--out", seq]):
        _one_line_refusal(capsys, argv, "a file of the trumans dataset", "choose an --out outside it")
    assert _bytes(synth_out) == before


def test_empty_out_is_refused_by_every_command(synth_out, tmp_path, monkeypatch, capsys):
    """`--out "$UNSET"` is refused by every command (it never means the current folder), before any work."""
    from helpers import CMU_WALK_BVH

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.txt").write_text("keep")
    seq = next((synth_out / "sequences").glob("*.npz"))
    for argv in (["sample"], ["refine", seq], ["track", seq, "--scene", "default"], ["view", seq],
                 ["train", "--data", synth_out], ["augment", "--data", synth_out],
                 ["data", "synth"], ["data", "import", CMU_WALK_BVH, "--format", "bvh"]):
        _one_line_refusal(capsys, [*argv, "--out", ""], "--out is empty")
    _one_line_refusal(capsys, ["data", "merge", " ", str(tmp_path)], "--out is empty")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.txt"]


def test_out_that_is_a_folder_or_the_current_folder_is_refused(synth_out, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    seq = next((synth_out / "sequences").glob("*.npz"))
    _one_line_refusal(capsys, ["refine", seq, "--out", tmp_path], "is a folder", "result.npz")
    _one_line_refusal(capsys, ["sample", "--out", "sub/"], "is a folder")
    for out in (".", "..", str(tmp_path)):
        _one_line_refusal(capsys, ["train", "--data", synth_out, "--out", out], "current folder")
    assert list(tmp_path.iterdir()) == []
