"""trumans.refine.outliers: flipped object rotations found by their neighbours' vote."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from trumans.refine.frame import FRAME_DIM, OBJ_R, OBJ_T
from trumans.refine.outliers import drop_object_flips, object_flip_labels, object_flip_mask, unflip_object
from trumans.rotations import matrix_to_6d, sixd_to_matrix


def _turning(T: int = 150, fps: float = 30.0, deg_per_s: float = 90.0) -> np.ndarray:
    """(T, 3, 3) an object turning steadily about z (a cup being tilted, a book turned)."""
    return Rotation.from_euler("z", (np.arange(T) / fps * deg_per_s)[:, None], degrees=True).as_matrix()


def test_a_flipped_run_is_found_and_a_steady_turn_is_not():
    R = _turning()
    flip = Rotation.from_rotvec([np.pi, 0, 0]).as_matrix()  # pi about the object's own x
    R[60:80] = R[60:80] @ flip
    obj6 = matrix_to_6d(R)
    obj6[100:105] = np.nan  # missing frames are never outliers
    mask = object_flip_mask(obj6, 30.0)
    assert mask[60:80].all() and mask.sum() == 20
    assert not object_flip_mask(matrix_to_6d(_turning()), 30.0).any()  # 90 deg/s is not a flip


def test_drop_object_flips_keeps_the_translation_and_the_rest():
    R = _turning(T=90)
    R[30:40] = R[30:40] @ Rotation.from_rotvec([0, np.pi, 0]).as_matrix()
    f = np.random.default_rng(0).normal(size=(90, FRAME_DIM)).astype(np.float32)
    f[:, OBJ_R] = matrix_to_6d(R)
    out = drop_object_flips(f, 30.0)
    assert np.isnan(out[30:40, OBJ_R]).all() and np.isfinite(np.delete(out, np.s_[30:40], 0)).all()
    np.testing.assert_array_equal(out[:, OBJ_T], f[:, OBJ_T])
    assert np.isfinite(f).all()  # the input is not changed


def _flip(axis: int) -> np.ndarray:
    v = np.zeros(3)
    v[axis] = np.pi
    return Rotation.from_rotvec(v).as_matrix()


def test_long_and_leading_flip_runs_are_read_from_the_whole_sequence():
    R = _turning(T=200)
    obs = R.copy()
    obs[0:45] = obs[0:45] @ _flip(1)  # the sequence starts flipped, for longer than the 1 s vote
    obs[100:170] = obs[100:170] @ _flip(2)  # a 2.3 s run
    obs[120:130] = obs[120:130] @ _flip(0)  # inside it, flipped about x as well (= about y overall)
    obj6 = matrix_to_6d(obs)
    obj6[60:75] = np.nan  # a gap is bridged (the object turns 45 deg in it)
    labels = object_flip_labels(obj6)
    want = np.zeros(200, int)
    want[0:45], want[100:170], want[120:130], want[60:75] = 2, 3, 2, -1  # S_x S_z = S_y
    np.testing.assert_array_equal(labels, want)
    assert object_flip_mask(obj6, 30.0)[100:170].sum() < 70  # the local vote alone misses most of it
    fixed = unflip_object(np.concatenate([np.zeros((200, OBJ_R.start)), obj6, np.zeros((200, FRAME_DIM - OBJ_R.stop))], 1))
    seen = labels >= 0
    np.testing.assert_allclose(sixd_to_matrix(fixed[seen][:, OBJ_R].astype(np.float64)), R[seen], atol=1e-5)
    assert np.isnan(fixed[60:75, OBJ_R]).all()


def test_flips_dense_enough_to_outvote_their_neighbours_are_still_found():
    rng = np.random.default_rng(3)
    R = _turning(T=240)
    noisy = Rotation.from_rotvec(rng.normal(0, 0.02, (240, 3))).as_matrix() @ R
    obs = noisy.copy()
    flipped = np.zeros(240, bool)
    for a in (20, 45, 75, 88):  # four runs close together: 60 % of frames 20..110 are flipped
        flipped[a:a + 20] = True
    obs[flipped] = obs[flipped] @ _flip(0)
    labels = object_flip_labels(matrix_to_6d(obs))
    np.testing.assert_array_equal(labels > 0, flipped)
    assert not object_flip_labels(matrix_to_6d(noisy)).any()  # noise and a steady turn are no flips


def test_a_step_no_flip_explains_cuts_the_chain():
    R = np.repeat(np.eye(3)[None], 100, 0)
    R[50:] = Rotation.from_rotvec([0, 0, np.radians(100)]).as_matrix()  # a 100 deg jump: neither a turn nor a flip
    R[60:70] = R[60:70] @ _flip(1)
    labels = object_flip_labels(matrix_to_6d(R))
    assert (labels[:60] == 0).all() and (labels[60:70] == 2).all() and (labels[70:] == 0).all()


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"\(T, 6\)"):
        object_flip_mask(np.zeros((10, 9)), 30.0)
    with pytest.raises(ValueError, match="max_angle_deg"):
        object_flip_mask(np.zeros((10, 6)), 30.0, max_angle_deg=200)
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        drop_object_flips(np.zeros((10, 6)), 30.0)
    with pytest.raises(ValueError, match=r"\(T, 6\)"):
        object_flip_labels(np.zeros((10, 4)))
    with pytest.raises(ValueError, match="max_step_deg"):
        object_flip_labels(np.zeros((10, 6)), max_step_deg=120)
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        unflip_object(np.zeros((10, 6)))
    assert (object_flip_labels(np.full((4, 6), np.nan)) == -1).all()


def test_frozen_frames_are_exact_repeats_and_become_missing():
    from trumans.refine.frame import IMU_R, JOINTS
    from trumans.refine.outliers import drop_frozen_frames, frozen_frame_mask

    f = np.random.default_rng(1).normal(size=(20, FRAME_DIM)).astype(np.float32)
    f[6:9] = f[5]  # the tracker repeats frame 5 three times
    f[12, JOINTS] = f[11, JOINTS] + 1e-6  # nearly still is not frozen
    f[15, 0] = np.nan
    f[16] = f[15]  # a frame with a missing joint is not compared
    mask = frozen_frame_mask(f)
    assert mask.tolist() == [i in (6, 7, 8) for i in range(20)]
    out = drop_frozen_frames(f)
    assert np.isnan(out[6:9, :IMU_R.start]).all() and np.isfinite(out[6:9, IMU_R.start:]).all()
    np.testing.assert_array_equal(np.delete(out, np.s_[6:9], 0), np.delete(f, np.s_[6:9], 0))
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        frozen_frame_mask(np.zeros((5, 10)))
