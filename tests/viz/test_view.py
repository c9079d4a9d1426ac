"""`trumans view`: GIF + top-down PNG from a sequence and a scene folder."""
import json

import imageio.v2 as imageio
import numpy as np
import pytest

from trumans.cli import main as cli_main
from trumans.dataset import write_index
from trumans.sequence import ObjectTrack, Sequence, save_sequence
from trumans.skeleton import REST_JOINTS


def _dataset(tmp_path):
    T = 20
    joints = REST_JOINTS[None] + np.linspace(0, 1, T)[:, None, None] * np.array([1.0, 0.0, 0.0])
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, 3] = joints[:, 21] + [0.0, 0.0, -0.05]
    contacts = np.zeros((T, 24), bool)
    contacts[:, 10] = True
    seq = Sequence(joints=joints, fps=30, contacts=contacts, scene="room_a",
                   objects={"cup_0": ObjectTrack(pose=pose, category="cup")})
    save_sequence(seq, tmp_path / "sequences" / "a.npz")
    grid = np.zeros((100, 100, 50), bool)
    grid[60:70, 40:60, :40] = True
    (tmp_path / "scenes" / "room_a").mkdir(parents=True)
    np.savez(tmp_path / "scenes" / "room_a" / "occupancy.npz", grid=grid, origin=np.array([-1.0, -1.0, 0.01]), voxel=np.asarray(0.02))
    write_index(tmp_path, {"name": "toy", "version": 1, "fps": 30.0, "vocabulary": [],
                           "scenes": {"room_a": "scenes/room_a"}, "splits": {"train": ["sequences/a.npz"]}})
    return tmp_path / "sequences" / "a.npz"


def test_view_writes_gif_and_png(tmp_path, capsys):
    path = _dataset(tmp_path)
    assert cli_main(["view", str(path), str(path), "--stride", "5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    frames = imageio.mimread(out["animation"])
    assert len(frames) == 4 and frames[0].shape[1] > frames[0].shape[0]  # two panels side by side
    png = imageio.imread(out["topdown"])
    assert png.ndim == 3 and png.shape[0] > 100
    # the occupied block (x in [0.2, 0.4]) is drawn: the image is not uniform
    assert png[..., :3].std() > 10


def test_view_bad_inputs(tmp_path):
    with pytest.raises(FileNotFoundError):
        cli_main(["view", str(tmp_path / "missing.npz")])
    path = _dataset(tmp_path)
    with pytest.raises(FileNotFoundError, match="scene folder"):
        cli_main(["view", str(path), "--scene", str(tmp_path / "nope")])


def test_still_draws_each_sequence_in_its_own_scene(tmp_path):
    """Original and augmented side by side: each panel shows its own scene (a box here, nothing
    there), at its own frame."""
    import trimesh

    from trumans.viz import SceneView, render_still

    path = _dataset(tmp_path)
    from trumans.sequence import load_sequence

    seq = load_sequence(path)
    box = SceneView(static=[trimesh.creation.box((2.0, 2.0, 1.0))], dynamic={})
    out = render_still([seq, seq], tmp_path / "s.png", [0, 19], [box, None], size_px=200)
    img = imageio.imread(out)[..., :3].astype(float)
    assert img.shape[:2] == (200, 400)
    left, right = img[:, :200], img[:, 200:]
    assert np.abs(left - right).mean() > 1.0  # the box is only in the left panel
    with pytest.raises(ValueError, match="one scene per sequence"):
        render_still([seq, seq], tmp_path / "t.png", 0, [box])
    with pytest.raises(ValueError, match="frame must be"):
        render_still([seq], tmp_path / "t.png", 20)
    with pytest.raises(ValueError, match=".png"):
        render_still([seq], tmp_path / "t.gif", 0)
    assert not (tmp_path / "t.png").exists()
