"""Written files and folders honour the umask (tempfile's private 0600 / 0700 would not)."""
import os
import stat

import numpy as np
import pytest
import trimesh

from trumans.scenes.atomic import atomic_write, umask_mode
from trumans.scenes.io import save_scene
from trumans.scenes.scene import Scene
from trumans.sequence import Sequence, save_sequence


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def _mode(p) -> int:
    return stat.S_IMODE(os.stat(p).st_mode)


def test_umask_mode_masks_the_requested_bits(umask_022):
    assert umask_mode(0o666) == 0o644 and umask_mode(0o777) == 0o755


def test_atomic_write_and_sequences_are_readable_by_others(tmp_path, umask_022):
    atomic_write(tmp_path / "a.txt", lambda p: open(p, "w").write("x"))
    assert _mode(tmp_path / "a.txt") == 0o644
    seq = Sequence(joints=np.zeros((3, 24, 3), np.float32), fps=30.0)
    save_sequence(seq, tmp_path / "s.npz")
    assert _mode(tmp_path / "s.npz") == 0o644
    old = os.umask(0o077)  # a private umask is honoured too
    try:
        atomic_write(tmp_path / "b.txt", lambda p: open(p, "w").write("x"))
    finally:
        os.umask(old)
    assert _mode(tmp_path / "b.txt") == 0o600


def test_saved_scene_folder_is_readable_by_others(tmp_path, umask_022):
    scene = Scene(name="box", static={"floor": trimesh.creation.box((2.0, 2.0, 0.1))})
    save_scene(scene, tmp_path / "box")
    assert _mode(tmp_path / "box") == 0o755
    assert all(_mode(p) == 0o644 for p in (tmp_path / "box").rglob("*") if p.is_file())
