"""The seat settle (``trumans.sample.cleanup.seat_settle``): every seated new frame's pelvis within the
tolerance of its seat height, the move faded into the neighbours, the context and far frames untouched."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.sample.cleanup.seat_settle import SeatSettleConfig, settle_on_seat
from trumans.skeleton import JOINT_INDEX, REST_JOINTS

PELVIS = JOINT_INDEX["pelvis"]
T, K = 16, 2


def _episode(pelvis_z: np.ndarray) -> np.ndarray:
    J = np.broadcast_to(REST_JOINTS, (1, T, 24, 3)).astype(np.float64).copy()
    J[..., 2] += (pelvis_z - J[0, 0, PELVIS, 2])[None, :, None]
    return J


def test_seated_frames_end_within_the_tolerance_and_the_body_moves_rigidly():
    z = np.full(T, 0.62)
    z[8:] = 0.60 + 0.06 * np.exp(-np.arange(T - 8) / 2.0)  # lands late: 6 cm high at the first seated frame
    target = np.full((1, T), np.nan)
    target[0, 8:] = 0.60
    J = _episode(z)
    out = settle_on_seat(J, target, K, SeatSettleConfig(tolerance=0.02, blend=3))
    err = out[0, 8:, PELVIS, 2] - 0.60
    assert np.all(np.abs(err) <= 0.02 + 1e-9), err
    np.testing.assert_allclose(err[0], 0.02, atol=1e-9)  # moved by the excess only, not onto the target
    delta = out - J
    np.testing.assert_allclose(delta[..., :2], 0.0)  # vertical only
    np.testing.assert_allclose(delta[..., 2], np.broadcast_to(delta[..., :1, 2], delta.shape[:-1]))  # whole body
    assert np.all(delta[0, :K] == 0.0)  # the context stays
    d = delta[0, :, PELVIS, 2]
    assert np.all(d[:5] == 0.0)  # more than `blend` frames before the sit phase: untouched
    assert d[5] < 0.0 and abs(d[5]) < abs(d[7]) < abs(d[8])  # the fade into the descent grows toward the seat


def test_no_seated_frame_or_within_tolerance_changes_nothing():
    J = _episode(np.full(T, 0.61))
    np.testing.assert_array_equal(settle_on_seat(J, np.full((1, T), np.nan), K), J)
    target = np.full((1, T), 0.60)
    np.testing.assert_array_equal(settle_on_seat(J, target, K, SeatSettleConfig(tolerance=0.02)), J)


def test_a_pelvis_sunk_into_the_seat_is_raised():
    J = _episode(np.full(T, 0.52))
    target = np.full((1, T), 0.60)
    out = settle_on_seat(J, target, K, SeatSettleConfig(tolerance=0.01))
    np.testing.assert_allclose(out[0, K:, PELVIS, 2], 0.59)
    np.testing.assert_array_equal(out[0, :K], J[0, :K])


def test_bad_inputs_are_refused():
    J = _episode(np.full(T, 0.6))
    with pytest.raises(ValueError, match="target_z"):
        settle_on_seat(J, np.zeros((1, T - 1)), K)
    with pytest.raises(ValueError, match="tolerance"):
        SeatSettleConfig(tolerance=-0.01)
    with pytest.raises(ValueError, match="blend"):
        SeatSettleConfig(blend=-1)
