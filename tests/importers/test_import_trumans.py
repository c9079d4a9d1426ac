"""TRUMANS release layout -> dataset format, on small arrays written in that layout."""
import json

import numpy as np
import pytest

from trumans.cli import main as cli_main
from trumans.importers.trumans_release import Y_UP_TO_Z_UP, read_release, release_grid_to_z_up
from trumans.sequence import load_sequence
from trumans.skeleton import REST_JOINTS


def _write_release(folder, n_per=(40, 25), n_actions=3, with_objects=True):
    folder.mkdir(parents=True, exist_ok=True)
    n = sum(n_per)
    rng = np.random.default_rng(0)
    # our rest pose (z-up) converted to y-up: p_yup = C^T p_zup
    zup = REST_JOINTS[None] + np.linspace(0, 1, n)[:, None, None] * np.array([1.0, 0.5, 0.0])
    joints_yup = zup @ Y_UP_TO_Z_UP  # row-vector form of C^T p
    np.save(folder / "human_joints.npy", joints_yup.astype(np.float32))
    np.save(folder / "action_label.npy", (rng.random((n, n_actions)) > 0.5).astype(np.float32))
    np.save(folder / "idx_start.npy", np.array([0, n_per[0]]))
    np.save(folder / "scene_flag.npy", np.array([0] * n_per[0] + [1] * n_per[1]))
    (folder / "Scene").mkdir(exist_ok=True)
    for k in range(2):
        g = np.zeros((300, 100, 400), dtype=bool)
        g[10:20, 0:5, 30:40] = True  # a block near the floor at x in [-2.8,-2.6], z_yup in [-3.4,-3.2]
        np.save(folder / "Scene" / f"scene_{k}.npy", g)
    if with_objects:
        flag = -np.ones((n, 2), dtype=np.int64)
        flag[:, 0] = 0
        mat = np.tile(np.eye(4), (n, 1, 1, 1))
        mat[:, 0, :3, 3] = [1.0, 0.0, 2.0]  # y-up translation
        np.save(folder / "object_flag.npy", flag)
        np.save(folder / "object_mat.npy", mat)
    return zup


def test_read_release_converts_to_z_up(tmp_path):
    zup = _write_release(tmp_path / "rel")
    rel = read_release(tmp_path / "rel", action_names=["a", "b", "c"])
    assert [s.num_frames for s in rel.sequences] == [40, 25]
    np.testing.assert_allclose(rel.sequences[0].joints, zup[:40], atol=1e-5)
    assert rel.sequences[0].joints[:, :, 2].min() > 0.0  # z is up, feet above floor
    assert rel.sequences[1].scene == "scene_1"
    assert rel.sequences[0].action_names == ["a", "b", "c"]
    pose = rel.sequences[0].objects["object_00"].pose
    np.testing.assert_allclose(pose[0, :3, 3], [1.0, -2.0, 0.0], atol=1e-6)  # (x, -z, y)


def test_release_grid_block_lands_where_expected():
    g = np.zeros((300, 100, 400), dtype=bool)
    g[10, 3, 30] = True  # centre (y-up) = (-3 + 0.21, 0.07, -4 + 0.61)
    sg = release_grid_to_z_up(g)
    idx = np.argwhere(sg.grid)[0]
    centre = sg.origin + idx * sg.voxel
    np.testing.assert_allclose(centre, [-2.79, 3.39, 0.07], atol=1e-9)  # (x, -z, y)


def test_cli_import_writes_dataset(tmp_path):
    _write_release(tmp_path / "rel")
    names = tmp_path / "names.json"
    names.write_text(json.dumps(["sit", "walk", "drink"]))
    rc = cli_main(["data", "import", str(tmp_path / "rel"), "--format", "trumans", "--out", str(tmp_path / "ds"),
                   "--action-names", str(names), "--fps", "10"])
    assert rc == 0
    index = json.loads((tmp_path / "ds" / "index.json").read_text())
    assert index["vocabulary"] == ["sit", "walk", "drink"]
    rels = sum(index["splits"].values(), [])
    assert len(rels) == 2
    seq = load_sequence(tmp_path / "ds" / rels[0])
    assert seq.fps == 10.0
    with np.load(tmp_path / "ds" / "scenes" / "scene_0" / "occupancy.npz") as z:
        assert z["grid"].shape == (300, 400, 100)


def test_bad_release_inputs(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_release(tmp_path / "nope")
    (tmp_path / "r").mkdir()
    with pytest.raises(FileNotFoundError, match="human_joints.npy"):
        read_release(tmp_path / "r")
    np.save(tmp_path / "r" / "human_joints.npy", np.zeros((5, 22, 3)))
    with pytest.raises(ValueError, match=r"\(N, 24, 3\)"):
        read_release(tmp_path / "r")
    np.save(tmp_path / "r" / "human_joints.npy", np.zeros((5, 24, 3)))
    np.save(tmp_path / "r" / "action_label.npy", np.zeros((5, 2)))
    with pytest.raises(ValueError, match="action names"):
        read_release(tmp_path / "r", action_names=["only_one"])
    (tmp_path / "r" / "action_label.npy").write_bytes(b"not a numpy file")
    with pytest.raises(ValueError, match="not a readable"):
        read_release(tmp_path / "r")


def test_a_npy_header_declaring_more_than_the_file_holds_is_refused_before_loading(tmp_path):
    from trumans.limits import check_npy_size

    good = tmp_path / "good.npy"
    np.save(good, np.zeros((4, 3), np.float32))
    check_npy_size(good)
    bomb = tmp_path / "human_joints.npy"
    header = {"descr": "<f4", "fortran_order": False, "shape": (1 << 20, 1 << 16, 3)}  # 768 GiB declared
    with open(bomb, "wb") as f:
        np.lib.format.write_array_header_1_0(f, header)
        f.write(b"\0" * 64)
    with pytest.raises(ValueError, match=r"declares .* GiB\) but holds 64 bytes"):
        check_npy_size(bomb)
    with pytest.raises(ValueError, match="declares"):
        read_release(tmp_path)


def test_release_objects_sharing_a_name_are_all_kept_and_nan_data_is_refused(tmp_path):
    import json as _json

    folder = tmp_path / "rel"
    _write_release(folder)
    flag = np.load(folder / "object_flag.npy")
    flag[:, 1] = 0  # the second object is present too
    np.save(folder / "object_flag.npy", flag)
    (folder / "object_names.json").write_text(_json.dumps(["chair", "chair"]))
    rel = read_release(folder, action_names=["a", "b", "c"])
    objs = rel.sequences[0].objects
    assert sorted(objs) == ["chair", "chair_1"] and {o.category for o in objs.values()} == {"chair"}

    mat = np.load(folder / "object_mat.npy")
    mat[5, 0, 0, 3] = np.nan
    np.save(folder / "object_mat.npy", mat)
    with pytest.raises(ValueError, match="object_mat.npy holds NaN or inf for object 'chair' at frame 5"):
        read_release(folder, action_names=["a", "b", "c"])
    labels = np.load(folder / "action_label.npy")
    labels[3, 1] = np.nan
    np.save(folder / "action_label.npy", labels)
    with pytest.raises(ValueError, match="action_label.npy holds NaN or inf \\(first at frame 3, column 1\\)"):
        read_release(folder, action_names=["a", "b", "c"])
