"""Offsets, fades, norm-weighted blending and the A13 smoothness bound (TRUMANS appendix B.5)."""
import numpy as np
import pytest

from trumans.augment.offsets import (ContactInterval, Tracks, blend_tracks, contact_tracks, fade, handover,
                             smooth_ratio)


def test_fade_is_a3_linear_window():
    w = fade(100, 40, 50, 10)
    assert np.all(w[40:50] == 1.0)
    assert w[35] == pytest.approx(0.5) and w[54] == pytest.approx(0.5)
    assert w[30] == 0.0 and w[59] == 0.0 and w[:30].sum() == 0.0
    with pytest.raises(ValueError, match="W must be > 0"):
        fade(10, 2, 4, 0)


def test_a5_norm_weighted_mean_of_two_offsets():
    T = 5
    v1, v2 = np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.3, 0.0])
    tr = Tracks(np.array([0, 0]), np.stack([np.full(T, 1.0), np.full(T, 0.5)]), np.stack([v1, v2]))
    off, win = blend_tracks(tr, T)
    a, b = 1.0 * v1, 0.5 * v2
    want = (np.linalg.norm(a) * a + np.linalg.norm(b) * b) / (np.linalg.norm(a) + np.linalg.norm(b))
    assert np.allclose(off[:, 0], want)
    assert win[:, 0].all() and not win[:, 1:].any()


def test_contact_offset_is_exact_inside_interval_and_fades_outside():
    T, W = 120, 30
    iv = ContactInterval(joint=0, obj="chair", start=50, end=70, offset=[0, 0, 0.15])
    off, win = blend_tracks(contact_tracks([iv], T, W), T)
    assert np.allclose(off[50:70, 0], [0, 0, 0.15])
    assert off[35, 0, 2] == pytest.approx(0.075)  # halfway through the fade-in
    assert not win[:21, 0].any() and win[21:99, 0].all() and not win[99:, 0].any()


def test_handover_ramps_a_zero_offset_contact_into_the_drift():
    T = 60
    iv = ContactInterval(joint=10, obj="floor", start=0, end=20)  # planted foot, zero offset
    own = contact_tracks([iv], T, 10)
    off, s = blend_tracks(own, T)
    drift = np.zeros((T, 24, 3))
    drift[:, 10] = [0.0, 0.0, 0.1]
    out, dn = handover(off, own.strength(), drift)
    assert np.allclose(out[:20, 10], 0.0)  # planted frames keep the foot where it was
    assert out[24, 10, 2] == pytest.approx(0.05)  # halfway into the hand-over
    assert out[28, 10, 2] == pytest.approx(0.09)
    assert dn[20:29, 10].max() == pytest.approx(0.1)


def test_handover_has_no_dip_when_offset_and_drift_agree():
    T = 80
    iv = ContactInterval(joint=20, obj="bed", start=0, end=30, offset=[0, 0, -0.1])
    own = contact_tracks([iv], T, 20)
    off, _ = blend_tracks(own, T)
    drift = np.zeros((T, 24, 3))
    drift[:, 20] = [0, 0, -0.1]
    out, _ = handover(off, own.strength(), drift)
    assert np.allclose(out[:49, 20], [0, 0, -0.1])


@pytest.mark.parametrize("seed", range(12))
def test_a13_bound_holds_on_random_cases(seed):
    rng = np.random.default_rng(seed)
    T, W = 200, float(rng.integers(5, 40))
    l = np.cumsum(rng.normal(0, 0.01, (T, 24, 3)), axis=0)
    ivs = []
    for _ in range(int(rng.integers(1, 8))):
        s = int(rng.integers(0, T - 10))
        ivs.append(ContactInterval(int(rng.integers(0, 24)), "o", s, s + int(rng.integers(1, 60)) if s + 60 < T else T,
                                   rng.normal(0, 0.1, 3)))
    own = contact_tracks(ivs, T, W)
    off, win = blend_tracks(own, T)
    drift = rng.normal(0, 0.1, (T, 24, 3))
    out, dn = handover(off, own.strength(), drift)
    r = smooth_ratio(l, l + out, own, W, mask=win, extra=dn)
    assert r.max() <= 1.0 + 1e-9


def test_interval_validation():
    with pytest.raises(ValueError, match="start < end"):
        ContactInterval(0, "o", 5, 5)
    with pytest.raises(ValueError, match="joint"):
        ContactInterval(24, "o", 0, 5)
