"""Sequence file format, action labels and resampling."""
import numpy as np
import pytest

from trumans.actions import ActionInterval, intervals_from_labels, labels_from_intervals, remap_labels
from trumans.resample import resample_sequence
from trumans.rotations import matrix_to_6d
from trumans.sequence import ObjectTrack, Sequence, load_sequence, save_sequence
from trumans.skeleton import REST_JOINTS


def _seq(T=12):
    rng = np.random.default_rng(1)
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, 0, 3] = np.arange(T)
    return Sequence(
        joints=REST_JOINTS[None] + rng.normal(0, 0.01, (T, 24, 3)), fps=30.0,
        rotations=matrix_to_6d(np.tile(np.eye(3), (T, 24, 1, 1))),
        actions=labels_from_intervals([ActionInterval("walk", 2, 9)], ["sit", "walk"], T),
        action_names=["sit", "walk"], contacts=rng.random((T, 24)) > 0.5, scene="room_0001",
        objects={"cup_0": ObjectTrack(pose=pose, category="cup")},
    )


def test_round_trip(tmp_path):
    s = _seq()
    save_sequence(s, tmp_path / "a.npz")
    r = load_sequence(tmp_path / "a.npz")
    np.testing.assert_array_equal(r.joints, s.joints)
    np.testing.assert_array_equal(r.contacts, s.contacts)
    assert r.action_names == ["sit", "walk"] and r.scene == "room_0001" and r.fps == 30.0
    np.testing.assert_allclose(r.objects["cup_0"].pose, s.objects["cup_0"].pose)
    assert r.objects["cup_0"].category == "cup"
    assert not list(tmp_path.glob(".*tmp"))  # nothing half-written left behind


def test_labels_progress():
    lab = labels_from_intervals([ActionInterval("walk", 2, 7), ActionInterval("sit", 5, 6)], ["sit", "walk"], 10)
    np.testing.assert_allclose(lab[2:7, 1], [1.0, 1.25, 1.5, 1.75, 2.0])
    assert lab[:2].sum() == 0 and lab[7:, 1].sum() == 0 and lab[5, 0] == 2.0
    ivs = intervals_from_labels(lab, ["sit", "walk"])
    assert ActionInterval("walk", 2, 7) in ivs and ActionInterval("sit", 5, 6) in ivs
    with pytest.raises(ValueError, match="unknown action 'run'"):
        labels_from_intervals([ActionInterval("run", 0, 3)], ["sit"], 5)
    np.testing.assert_array_equal(remap_labels(lab, ["sit", "walk"], ["walk", "x", "sit"])[:, [0, 2]], lab[:, [1, 0]])


def test_bad_sequences(tmp_path):
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        Sequence(joints=np.zeros((5, 22, 3)), fps=30)
    bad = np.zeros((5, 24, 3)); bad[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        Sequence(joints=bad, fps=30)
    with pytest.raises(ValueError, match="fps"):
        Sequence(joints=np.zeros((5, 24, 3)), fps=0)
    with pytest.raises(FileNotFoundError):
        load_sequence(tmp_path / "missing.npz")
    (tmp_path / "c.npz").write_bytes(b"garbage")
    with pytest.raises(ValueError, match="not a readable"):
        load_sequence(tmp_path / "c.npz")


def test_resample_30_to_10():
    s = _seq(T=31)
    r = resample_sequence(s, 10.0)
    assert r.num_frames == 11 and r.fps == 10.0
    np.testing.assert_allclose(r.joints, s.joints[::3], atol=1e-6)
    np.testing.assert_allclose(r.objects["cup_0"].pose[:, 0, 3], np.arange(0, 31, 3), atol=1e-5)
    np.testing.assert_array_equal(r.contacts, s.contacts[::3])
