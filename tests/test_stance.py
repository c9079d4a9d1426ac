"""trumans.stance.planted: the one foot-stance detector (generator foot cleanup, refine drift / lock)."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.stance import planted


def test_hysteresis_holds_between_thresholds() -> None:
    speed = np.array([0.1, 0.5, 0.9, 0.5, 0.1, 0.5])[:, None]  # (T, 1) m/s
    out = planted(speed, enter_speed=0.35, exit_speed=0.8)[:, 0]
    # enters at 0.1, holds through 0.5 (between thresholds), leaves at 0.9, stays off at 0.5, enters again
    np.testing.assert_array_equal(out, [True, True, False, False, True, True])
    # with one threshold it is a plain comparison
    np.testing.assert_array_equal(planted(speed, enter_speed=0.35)[:, 0], speed[:, 0] < 0.35)


def test_height_ends_a_contact_and_initial_state_fills_undecided_frames() -> None:
    speed = np.full((5, 2), 0.5)  # between 0.35 and 0.8: never decisive by speed
    height = np.array([[0.08, 0.2], [0.08, 0.08], [0.02, 0.08], [0.08, 0.08], [0.2, 0.08]])  # m above rest
    out = planted(speed, height, enter_speed=0.6, exit_speed=0.8, enter_height=0.06, exit_height=0.1,
                  initial=np.array([True, True]))
    np.testing.assert_array_equal(out[:, 0], [True, True, True, True, False])  # initial, held, entered, held, left
    np.testing.assert_array_equal(out[:, 1], [False, False, False, False, False])  # left at frame 0, never re-entered


def test_short_runs_dropped_and_batched_shapes() -> None:
    speed = np.ones((3, 10, 4))
    speed[:, 2:4] = 0.0  # a 2-frame stance
    speed[:, 5:9] = 0.0  # a 4-frame stance
    out = planted(speed, enter_speed=0.2, min_frames=3)
    assert out.shape == (3, 10, 4) and out.dtype == bool
    expected = np.zeros(10, bool)
    expected[5:9] = True
    assert (out == expected[None, :, None]).all()


@pytest.mark.parametrize("kwargs, msg", [
    (dict(speed=np.zeros(5), enter_speed=0.2), "speed must be"),
    (dict(speed=np.zeros((5, 2)), height=np.zeros((5, 3)), enter_speed=0.2), "one shape"),
    (dict(speed=np.zeros((5, 2)), enter_speed=0.5, exit_speed=0.2), "enter_speed <= exit_speed"),
])
def test_bad_arguments(kwargs, msg) -> None:
    with pytest.raises(ValueError, match=msg):
        planted(**kwargs)
