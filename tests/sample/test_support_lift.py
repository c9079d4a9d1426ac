"""Support lift (trumans.sample.cleanup.support_lift): weights from the action labels, the body raised onto its feet."""
import numpy as np
import pytest

from trumans.skeleton import FOOT_REST_HEIGHT
from trumans.sample.cleanup.support_lift import lift_onto_feet, lowest_foot_height, support_weights
from trumans.skeleton import JOINT_INDEX

VOCAB = ["walk", "stand", "sit_down", "sit", "stand_up", "lie", "drink"]
LA, RA, LT, RT = (JOINT_INDEX[n] for n in ("left_ankle", "right_ankle", "left_foot", "right_foot"))


def _labels(rows: list[dict[str, float]]) -> np.ndarray:
    """One frame per dict: action -> progress in [0, 1] (stored as 1 + progress)."""
    out = np.zeros((len(rows), len(VOCAB)))
    for t, r in enumerate(rows):
        for name, p in r.items():
            out[t, VOCAB.index(name)] = 1.0 + p
    return out


def test_weights_follow_the_posture():
    lab = _labels([{"walk": 0.3}, {"stand": 0.0, "drink": 0.5}, {"sit": 0.2}, {"lie": 0.9},
                   {"sit_down": 0.0}, {"sit_down": 0.5}, {"sit_down": 1.0},
                   {"stand_up": 0.0}, {"stand_up": 0.5}, {"stand_up": 1.0}, {}])
    w = support_weights(lab, VOCAB)
    np.testing.assert_allclose(w, [1, 1, 0, 0, 1, 0.5, 0, 0, 0.5, 1, 1], atol=1e-12)
    # a batch axis is kept; a vocabulary without the seated actions carries every frame
    assert support_weights(np.stack([lab, lab]), VOCAB).shape == (2, len(lab))
    np.testing.assert_array_equal(support_weights(np.zeros((4, 2)), ["walk", "drink"]), np.ones(4))


def _body(feet_z: float, T: int = 5) -> np.ndarray:
    """(1, T, 24, 3): joints 1 m up, the lowest foot joint ``feet_z`` from its rest height."""
    J = np.ones((1, T, 24, 3))
    J[..., [LA, RA], 2] = FOOT_REST_HEIGHT[0] + 0.2
    J[..., LT, 2] = FOOT_REST_HEIGHT[2] + feet_z
    J[..., RT, 2] = FOOT_REST_HEIGHT[2] + 0.3
    return J


def test_lift_puts_the_lowest_foot_back_on_the_floor_rigidly():
    J = _body(-0.07)
    out = lift_onto_feet(J, np.ones((1, 5)))
    np.testing.assert_allclose(lowest_foot_height(out), 0.0, atol=1e-12)
    d = out - J
    np.testing.assert_allclose(d[..., :2], 0.0)
    np.testing.assert_allclose(d[..., 2], 0.07)  # every joint the same: bone lengths and pose unchanged
    half = lift_onto_feet(J, np.full((1, 5), 0.5))
    np.testing.assert_allclose(half[..., 2] - J[..., 2], 0.035)


def test_lift_never_lowers_and_keeps_the_context():
    up = _body(0.04)
    np.testing.assert_array_equal(lift_onto_feet(up, np.ones((1, 5))), up)  # feet above the floor: unchanged
    J = _body(-0.05)
    out = lift_onto_feet(J, np.ones((1, 5)), fixed=2)
    np.testing.assert_array_equal(out[:, :2], J[:, :2])
    np.testing.assert_allclose(out[:, 2:, :, 2] - J[:, 2:, :, 2], 0.05)
    np.testing.assert_array_equal(lift_onto_feet(J, np.zeros((1, 5))), J)  # seated frames: weight 0


def test_bad_inputs_raise():
    J = _body(-0.05)
    with pytest.raises(ValueError, match="weight"):
        lift_onto_feet(J, np.ones((1, 4)))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        lift_onto_feet(J, np.full((1, 5), 1.5))
    with pytest.raises(ValueError, match="finite"):
        lift_onto_feet(J, np.full((1, 5), np.nan))
    with pytest.raises(ValueError, match="vocabulary"):
        support_weights(np.zeros((3, 4)), VOCAB)


def test_no_support_lift_flag():
    import argparse

    from trumans.sample.sampling_args import add_postprocess_arguments, postprocess_kwargs

    p = argparse.ArgumentParser()
    add_postprocess_arguments(p)
    assert postprocess_kwargs(p.parse_args([]))["cleanup"].support_lift.enabled is True
    assert postprocess_kwargs(p.parse_args(["--no-support-lift"]))["cleanup"].support_lift.enabled is False
