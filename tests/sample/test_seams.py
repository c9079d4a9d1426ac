"""Seam blending (trumans.sample.cleanup.seam): the new frames continue the context's velocity, then the network's."""
import numpy as np
import pytest

from trumans.sample.cleanup.seam import blend_seam, seam_weights
from trumans.eval.synthesis_metrics import transition_jerk_ratio


def test_weights_fall_smoothly_from_one_to_zero():
    w = seam_weights(8, 4)
    np.testing.assert_allclose(w[[0, 2]], [1.0, 0.5])
    assert (np.diff(w) <= 0).all() and (w[4:] == 0).all()
    np.testing.assert_array_equal(seam_weights(5, 0), 0.0)
    with pytest.raises(ValueError, match="frames"):
        seam_weights(5, -1)


def test_blend_removes_a_jump_and_keeps_the_motion_after_it():
    t = np.arange(30, dtype=np.float64)
    walk = np.zeros((1, 30, 24, 3))
    walk[..., 0] = 0.1 * t[None, :, None]  # 1 m/s at 10 fps, every joint
    walk[..., 2] = 0.02 * np.sin(t / 2)[None, :, None]
    jumped = walk.copy()
    jumped[:, 10:, :, 1] += 0.08  # the new episode starts 8 cm aside
    new = blend_seam(jumped[:, 8:10], jumped[:, 10:], frames=4)
    out = np.concatenate([jumped[:, :10], new], 1)
    np.testing.assert_allclose(out[0, 10, :, 0], 2 * out[0, 9, :, 0] - out[0, 8, :, 0])  # continues the velocity
    np.testing.assert_allclose(out[0, 10, :, 1], 0.0, atol=1e-12)
    np.testing.assert_array_equal(out[:, 14:], jumped[:, 14:])  # the network's motion after the blend
    seams = [10]
    assert transition_jerk_ratio(out[0], seams) < 0.5 * transition_jerk_ratio(jumped[0], seams)
    np.testing.assert_array_equal(blend_seam(jumped[:, 8:10], jumped[:, 10:], frames=0), jumped[:, 10:])
    with pytest.raises(ValueError, match="context"):
        blend_seam(jumped[:, 9:10], jumped[:, 10:])
