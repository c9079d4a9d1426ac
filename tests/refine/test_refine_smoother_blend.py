"""trumans.refine.smoother_blend: a Gaussian smoother of the input takes an inverse-variance share
where the filter disagrees with it by more than the input's noise explains."""
import numpy as np
import pytest

from trumans.refine.smoother_blend import BlendConfig, blend_with_smoother, smoother_weights
from trumans.skeleton import FOOT_JOINTS, JOINT_INDEX

FPS = 30.0
WRIST = JOINT_INDEX["left_wrist"]


def _truth(T: int = 150) -> np.ndarray:
    """A smooth body: every joint on its own slow circle (radius 10 cm, 0.3-0.6 Hz)."""
    t = np.arange(T)[:, None] / FPS
    f = 0.3 + 0.3 * np.arange(24)[None] / 23
    G = np.zeros((T, 24, 3))
    G[..., 0], G[..., 1], G[..., 2] = 0.1 * np.cos(2 * np.pi * f * t), 0.1 * np.sin(2 * np.pi * f * t), 1.0
    return G + np.random.default_rng(9).normal(0, 0.3, (1, 24, 3))


def test_a_clean_input_with_a_filter_that_agrees_gets_no_share():
    G = _truth()
    w, S = smoother_weights(G, G, FPS)
    assert w.max() < 0.05  # the only disagreement is the smoother's own blur, which e_S^2 predicts
    np.testing.assert_allclose(blend_with_smoother(G, G, FPS), G, atol=2e-5)


def test_a_filter_wrong_on_one_joint_is_pulled_to_the_smoothed_input():
    """A jittery input (1 cm per axis) and a filter exact everywhere but on the left wrist, where it
    is 4 cm off in a 0.3-s wobble: the wrist's weight rises and its error falls; a joint on which
    the filter is right keeps most of the filter's (a small share: the smoother there is worse)."""
    rng = np.random.default_rng(0)
    G = _truth()
    X = G + rng.normal(0, 0.01, G.shape)
    F = G.copy()
    t = np.arange(len(G)) / FPS
    F[:, WRIST, 0] += 0.04 * np.sin(2 * np.pi * t / 0.3)
    w, _ = smoother_weights(F, X, FPS)
    out = blend_with_smoother(F, X, FPS)
    err = lambda J, j: np.linalg.norm(J[:, j] - G[:, j], axis=-1).mean()  # noqa: E731
    assert w[:, WRIST].mean() > 0.6
    assert err(out, WRIST) < 0.5 * err(F, WRIST)
    other = JOINT_INDEX["right_elbow"]
    assert w[:, other].mean() < 0.15 and err(out, other) < 0.004


def test_failures_and_feet_keep_the_filters():
    rng = np.random.default_rng(1)
    G = _truth()
    X = G + rng.normal(0, 0.01, G.shape)
    F = G + 0.03  # the filter 5 cm off everywhere: the smoother earns a share wherever it may
    X[70, WRIST] += 0.3  # a spike
    X[100:110, WRIST] = np.nan  # a gap
    w, S = smoother_weights(F, X, FPS, BlendConfig(fail_pad=2))
    assert np.isfinite(S).all()
    assert (w[68:73, WRIST] == 0).all() and (w[98:112, WRIST] == 0).all()
    assert w[20:60, WRIST].min() > 0.5
    assert (w[:, list(FOOT_JOINTS)] == 0).all()
    assert smoother_weights(F, X, FPS, BlendConfig(feet=True))[0][20:60, list(FOOT_JOINTS)].min() > 0.5


def test_bad_inputs():
    G = _truth(40)
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        smoother_weights(G[:, :10], G, FPS)
    bad = G.copy()
    bad[3, 2, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        smoother_weights(bad, G, FPS)
    with pytest.raises(ValueError, match="fps"):
        smoother_weights(G, G, 0.0)
    for kw, name in ((dict(sigma_frames=0.0), "sigma_frames"), (dict(window_s=-1.0), "window_s"),
                     (dict(fail_pad=-1), "fail_pad")):
        with pytest.raises(ValueError, match=name):
            BlendConfig(**kw)
