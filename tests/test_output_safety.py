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
    with DatasetWriter(out, "data synth", {"seed": 0}):
        (out / "sequences").mkdir()
        (out / "sequences" / "a.npz").write_text("x")
        os.symlink(elsewhere, out / "scenes")
    with DatasetWriter(out, "data synth", {"seed": 1}, overwrite=True):  # other settings: replaced
        pass
    assert not (out / "sequences").exists() and not (out / "scenes").exists()
    assert (elsewhere / "keep.txt").read_text() == "keep"


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
