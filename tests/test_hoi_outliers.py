"""trumans.hoi.outliers: flipped object rotations found by their neighbours' vote."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from trumans.hoi.frame import FRAME_DIM, OBJ_R, OBJ_T
from trumans.hoi.outliers import drop_object_flips, object_flip_mask
from trumans.rotations import matrix_to_6d


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


def test_bad_inputs():
    with pytest.raises(ValueError, match=r"\(T, 6\)"):
        object_flip_mask(np.zeros((10, 9)), 30.0)
    with pytest.raises(ValueError, match="max_angle_deg"):
        object_flip_mask(np.zeros((10, 6)), 30.0, max_angle_deg=200)
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        drop_object_flips(np.zeros((10, 6)), 30.0)


def test_frozen_frames_are_exact_repeats_and_become_missing():
    from trumans.hoi.frame import IMU_R, JOINTS
    from trumans.hoi.outliers import drop_frozen_frames, frozen_frame_mask

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
