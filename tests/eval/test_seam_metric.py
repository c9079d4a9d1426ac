"""seam_jerk_peak_ratio (trumans.eval.synthesis_metrics): jerk folded on the episode cycle, analytic cases."""
import numpy as np
import pytest

from trumans.eval.synthesis_metrics import folded_jerk, real_seam_reference, seam_jerk_peak_ratio

CYCLE = 14


def _circle(T: int, period: float = 23.0) -> np.ndarray:
    """(T, 24, 3) every joint on a horizontal circle of 10 cm: a constant jerk magnitude, no cycle."""
    t = np.arange(T, dtype=np.float64)
    j = np.zeros((T, 24, 3))
    j[..., 0] = 0.1 * np.cos(2 * np.pi * t / period)[:, None]
    j[..., 1] = 0.1 * np.sin(2 * np.pi * t / period)[:, None]
    return j


def test_smooth_motion_gives_one():
    r, _ = seam_jerk_peak_ratio(_circle(30 * CYCLE), CYCLE)
    assert abs(r - 1.0) < 1e-6
    t = np.arange(30 * CYCLE, dtype=np.float64)  # a sine whose period does not divide the cycle
    j = np.zeros((len(t), 24, 3))
    j[..., 2] = 0.05 * np.sin(2 * np.pi * t / 11.3)[:, None]
    r, _ = seam_jerk_peak_ratio(j, CYCLE)
    assert 1.0 <= r < 1.15


def test_a_jump_every_cycle_peaks_at_the_seam():
    first = 2  # an episode's first new frame after k = 2 context frames
    j = _circle(30 * CYCLE)
    for s in range(first, len(j), CYCLE):
        j[s:, :, 2] += 0.01  # 1 cm hitch between frames s - 1 and s
    r, phase = seam_jerk_peak_ratio(j, CYCLE, first)
    assert r > 3.0 and phase == 0
    f = folded_jerk(j, CYCLE, first)
    assert f.shape == (CYCLE,) and np.argmax(f) == 0
    # folded on another cycle the hitches spread over the phases: no peak
    r_other, _ = seam_jerk_peak_ratio(j, CYCLE + 3, first)
    assert r_other < 0.5 * r


def test_peak_grows_with_the_hitch():
    base = _circle(20 * CYCLE)
    ratios = []
    for size in (0.0, 0.002, 0.02):
        j = base.copy()
        for s in range(0, len(j), CYCLE):
            j[s:, :, 0] += size
        ratios.append(seam_jerk_peak_ratio(j, CYCLE)[0])
    assert ratios[0] < ratios[1] < ratios[2]


def test_short_or_still_motion_and_bad_input():
    assert np.isnan(seam_jerk_peak_ratio(_circle(CYCLE), CYCLE)[0])  # less than two cycles
    assert np.isnan(seam_jerk_peak_ratio(np.zeros((10 * CYCLE, 24, 3)), CYCLE)[0])  # does not move
    with pytest.raises(ValueError, match="cycle"):
        folded_jerk(_circle(100), 1)
    with pytest.raises(ValueError, match=r"\(T, J, 3\)"):
        folded_jerk(np.zeros((100, 24)), CYCLE)


def test_real_corpus_has_no_seam_peak():
    med, lo, hi, n = real_seam_reference(CYCLE, 10.0)
    assert n >= 10 and 1.0 < lo <= med <= hi < 1.6


def test_pelvis_speed_max_finds_a_one_frame_jump():
    from trumans.eval.synthesis_metrics import pelvis_speed_max

    T, fps = 30, 10.0
    J = np.zeros((T, 24, 3))
    J[:, :, 0] = (np.arange(T) * 0.13)[:, None]  # a steady 1.3 m/s walk
    assert pelvis_speed_max(J, fps) == pytest.approx(1.3)
    J[12:, :, 1] += 0.3  # thrown 30 cm sideways in one frame
    assert pelvis_speed_max(J, fps) == pytest.approx(np.hypot(0.13, 0.3) * fps)
    assert pelvis_speed_max(J[:1], fps) == 0.0
    with pytest.raises(ValueError, match="fps"):
        pelvis_speed_max(J, 0.0)
