"""Runs and contact intervals (trumans.contacts.intervals): half-open [start, end) everywhere."""
import numpy as np
import pytest

from trumans.actions import ActionInterval, intervals_from_labels, labels_from_intervals
from trumans.contacts.intervals import JointContact, joint_contact_intervals
from trumans.intervals import run_bounds, runs
from trumans.eval.metrics import foot_slides


def test_runs_closes_small_gaps_and_drops_short_runs():
    m = np.zeros(30, bool)
    m[2:6] = m[7:12] = m[20:21] = True
    assert runs(m, max_gap=1) == [(2, 12), (20, 21)]
    assert runs(m, max_gap=0, min_len=2) == [(2, 6), (7, 12)]


def test_run_bounds_half_open_at_the_edges():
    m = np.array([1, 1, 0, 1, 0, 0, 1], bool)
    s, e = run_bounds(m)
    assert s.tolist() == [0, 3, 6] and e.tolist() == [2, 4, 7]
    assert runs(np.zeros(5, bool)) == [] and runs(np.ones(5, bool)) == [(0, 5)]
    assert runs(np.zeros(0, bool)) == []
    # the frames of the runs are exactly the True frames
    rng = np.random.default_rng(0)
    m = rng.random(200) < 0.4
    back = np.zeros_like(m)
    for a, b in runs(m):
        back[a:b] = True
    assert (back == m).all()


def test_runs_bad_input():
    with pytest.raises(ValueError, match="max_gap"):
        runs(np.ones(4, bool), max_gap=-1)
    with pytest.raises(ValueError, match=r"\(T,\)"):
        run_bounds(np.ones((2, 2), bool))


def test_joint_contact_intervals_per_joint_and_object():
    idx = np.full((12, 24), -1)
    idx[0:5, 10] = 0  # left foot on the floor
    idx[5:7, 10] = -1
    idx[7:12, 10] = 0
    idx[3:9, 20] = 1  # left wrist on the cup, with a one-frame gap
    idx[5, 20] = -1
    names = ["floor_plane", "cup"]
    got = joint_contact_intervals(idx, names, max_gap=1)
    assert got == [JointContact(10, "floor_plane", 0, 5), JointContact(10, "floor_plane", 7, 12),
                   JointContact(20, "cup", 3, 9)]
    assert joint_contact_intervals(idx, names, max_gap=2)[0] == (10, "floor_plane", 0, 12)
    with pytest.raises(ValueError, match="names has 1"):
        joint_contact_intervals(idx, names[:1])


def test_action_labels_and_foot_slides_use_the_same_runs():
    lab = labels_from_intervals([ActionInterval("walk", 2, 7)], ["walk"], 10)
    (iv,) = intervals_from_labels(lab, ["walk"])
    assert runs(lab[:, 0] > 0) == [(iv.start, iv.end)] == [(2, 7)]  # one half-open convention
    foot = np.zeros((10, 1, 3))
    foot[:, 0, 0] = np.arange(10) * 0.01  # slides 1 cm per frame
    contact = np.zeros((10, 1), bool)
    contact[2:5, 0] = True  # frames 2, 3, 4: two frame steps
    np.testing.assert_allclose(foot_slides(foot, contact), [0.02])


def test_joint_centre_inside_vs_body_penetration():
    """joint_centre_inside_cm measures joint centres only; penetration_max_cm the body around them."""
    import trimesh

    from trumans.scenes.scene import Scene, SceneObject
    from trumans.eval.metrics import joint_centre_inside_cm, penetration_depth, penetration_max_cm

    pose = np.eye(4)
    pose[:3, 3] = [2.0, 0.0, 0.4]
    box = SceneObject("box", "table", trimesh.creation.box((1.0, 1.0, 0.8)), pose=pose)  # top at z = 0.8
    scene = Scene(name="s", objects={"box": box})
    joints = np.zeros((3, 24, 3))
    joints[:, :, 2] = 1.5  # everything far above
    joints[1, 20] = [2.0, 0.0, 0.75]  # left wrist centre 5 cm inside the top
    assert abs(joint_centre_inside_cm(joints, scene, ["box"]) - 5.0) < 1e-3
    assert joint_centre_inside_cm(joints[[0, 2]], scene, ["box"]) == 0.0
    assert joint_centre_inside_cm(joints, scene, []) == 0.0
    with pytest.raises(ValueError, match="not in scene"):
        joint_centre_inside_cm(joints, scene, ["sofa"])
    # the same wrist 1 cm *above* the top: no centre inside, but the palm (3 cm radius) is 2 cm in
    signed = np.full((1, 24), 1.0)
    signed[0, 20] = 0.01
    assert abs(penetration_max_cm(penetration_depth(signed)) - 2.0) < 1e-9
