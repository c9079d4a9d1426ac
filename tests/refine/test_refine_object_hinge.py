"""trumans.refine.object_hinge: a hinged object's translation from its rotation and one fitted hinge."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from trumans.refine.frame import FRAME_DIM, OBJ_R, OBJ_T
from trumans.refine.object_hinge import HINGED_CATEGORIES, fit_hinge
from trumans.rotations import matrix_to_6d, sixd_to_matrix

FPS = 30.0


def _door(T: int = 180, turn_deg: float = 70.0, seed: int = 0):
    """A door leaf (origin at its bottom centre, hinge 0.45 m to its side) that rests, swings open
    and rests: (truth (T, 235), R (T, 3, 3), hinge world point (3,))."""
    t = np.arange(T)
    angle = np.radians(turn_deg) * np.clip((t - 50) / 60, 0, 1)
    base = Rotation.from_euler("z", 0.4)  # the closed door's heading
    R = (Rotation.from_euler("z", angle[:, None]) * base).as_matrix()
    u = np.array([0.02, 0.45, 0.0])  # the hinge in the door's frame
    hinge = np.array([1.5, -0.3, 0.0])
    truth = np.random.default_rng(seed).normal(size=(T, FRAME_DIM))
    truth[:, OBJ_T] = hinge - R @ u
    truth[:, OBJ_R] = matrix_to_6d(R)
    return truth, R, hinge


def test_fit_hinge_recovers_the_swing_from_rotations_and_drifting_translations():
    truth, R, hinge = _door()
    T = len(truth)
    rng = np.random.default_rng(1)
    d = np.array([0.02, -0.01, 0.015])  # the drift's mean over the clip: not observable, stays
    wiggle = 0.03 * np.stack([np.sin(2 * np.pi * (k + 1) * np.arange(T) / T + k) for k in range(3)], -1)
    drift = d + wiggle  # slow tracker drift
    tracked = truth.copy()
    tracked[:, OBJ_T] += drift + rng.normal(0, 0.005, (T, 3))
    tracked[30:40, OBJ_T] = np.nan  # missing frames are skipped
    filtered = truth.copy()
    wobble = Rotation.from_rotvec(rng.normal(0, np.radians(1.0), (T, 3)))  # off-axis rotation noise
    filtered[:, OBJ_R] = matrix_to_6d((wobble * Rotation.from_matrix(R)).as_matrix())
    filtered[:, OBJ_T] = np.nan_to_num(tracked[:, OBJ_T])  # what the filter would leave: the drift
    out = fit_hinge(filtered, tracked)
    err = np.linalg.norm(out[:, OBJ_T] - truth[:, OBJ_T], axis=-1)
    err_in = np.nanmean(np.linalg.norm(tracked[:, OBJ_T] - truth[:, OBJ_T], axis=-1))
    assert err.mean() < 0.8 * err_in  # the drift's changes are averaged over the whole sequence
    # a drift without changes is all that stays: the swing's shape comes from the rotation
    tracked[:, OBJ_T] = truth[:, OBJ_T] + d + rng.normal(0, 0.005, (T, 3))
    left = fit_hinge(filtered, tracked)[:, OBJ_T] - truth[:, OBJ_T] - d
    assert np.linalg.norm(left, axis=-1).mean() < 0.01 and np.linalg.norm(left, axis=-1).max() < 0.035
    # the rotations keep one dof: every frame turns about one world axis from the first
    rel = Rotation.from_matrix(sixd_to_matrix(out[:, OBJ_R])) * Rotation.from_matrix(sixd_to_matrix(out[:1, OBJ_R])).inv()
    axes = rel.as_rotvec()[60:] / np.linalg.norm(rel.as_rotvec()[60:], axis=1, keepdims=True)
    assert np.abs(axes @ axes[-1]).min() > 1 - 1e-6 and abs(abs(axes[-1, 2]) - 1) < 0.01
    np.testing.assert_array_equal(out[:, :OBJ_T.start], filtered[:, :OBJ_T.start])  # the body is untouched


def test_fit_hinge_leaves_an_object_that_hardly_turns_and_bad_inputs_fail():
    truth, R, _ = _door(turn_deg=6.0)
    tracked = truth.copy()
    tracked[:, OBJ_T] += 0.02
    assert np.array_equal(fit_hinge(truth, tracked), truth)  # 6 deg: the hinge is not identifiable
    tracked[:, OBJ_T] = np.nan
    truth2, _, _ = _door()
    assert np.array_equal(fit_hinge(truth2, tracked), truth2)  # no observed translation
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        fit_hinge(truth[:, :10], truth)
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        fit_hinge(truth, truth[:-1])
    bad = truth2.copy()
    bad[5, OBJ_R] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_hinge(bad, truth2)


def test_hinged_categories_are_the_data_worlds_hinged_objects():
    from trumans.scenes.furniture import door

    d = door(np.random.default_rng(0), "door_0", wall_thickness=0.12)
    assert d.dof == "hinge" and d.category in HINGED_CATEGORIES
