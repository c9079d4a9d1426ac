"""Post-episode push-out of the body from the scene (trumans.sample.cleanup.scene_pushout) and its place in the rollout."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.scenes.occupancy import OccupancyGrid
from trumans.sample.cleanup.foot import clean_feet
from trumans.skeleton import LEG_CHAINS
from trumans.sample.guidance.penetration import SceneSDF
from trumans.sample.sampler import bone_lengths_of
from trumans.sample.cleanup.scene_pushout import PushOutConfig, push_out, push_radii, seam_spline_basis

from trumans.skeleton import JOINT_INDEX

from helpers import box_room, standing_body

FPS = 30.0


def _depth(sdf: SceneSDF, J: np.ndarray) -> np.ndarray:
    """(..., 24) depth of the body (push radii, no margin) inside the scene, m."""
    return np.maximum(push_radii() - sdf(torch.as_tensor(J, dtype=torch.float32)).numpy(), 0.0)


def _walk_into_box(T: int = 40, k: int = 4) -> np.ndarray:
    """A standing body (1, T, 24, 3) whose hips slide from 20 cm in front of the box (x = 1.0) to
    6 cm inside the box's front face over the new frames, the context (first k frames) outside."""
    J = standing_body(T)
    J[..., 1] += 1.0
    J[..., 0] += 0.8 + np.r_[np.zeros(k), np.linspace(0.0, 0.26, T - k)][None, :, None]
    return J


def test_spline_basis_vanishes_at_the_seam():
    D = seam_spline_basis(20, 4)
    assert D.shape[0] == 21 and np.abs(D[0]).max() == 0
    np.testing.assert_allclose(D[-8:].sum(1), 1.0, atol=1e-9)  # a constant offset is representable


def test_body_walking_into_a_box_is_pushed_out_smoothly_with_context_and_bones_kept():
    sdf, k = SceneSDF(box_room()), 4
    J = _walk_into_box(k=k)
    assert _depth(sdf, J).max() > 0.08  # the hips' skin 8+ cm into the box
    out = push_out(J, sdf, fixed=k)
    np.testing.assert_array_equal(out[:, :k], J[:, :k])
    assert _depth(sdf, out).max() < 0.015
    d = out - J  # a rigid translation per frame
    np.testing.assert_allclose(d, np.broadcast_to(d[:, :, :1], d.shape), atol=1e-6)
    np.testing.assert_allclose(bone_lengths_of(out), bone_lengths_of(J), atol=1e-5)
    jerk = np.abs(np.diff(d[0, :, 0, 0], n=3)).max()
    assert jerk < 0.01  # m / frame^3: a smooth offset, no jump at the seam
    # a body already clear of the scene is left exactly as it was
    clear = J.copy()
    clear[..., 0] -= 0.5
    np.testing.assert_array_equal(push_out(clear, sdf, fixed=k), clear)


def _objective(J: np.ndarray, out: np.ndarray, sdf: SceneSDF, k: int, c: PushOutConfig = PushOutConfig()) -> float:
    """The push-out's objective (module doc) of the offsets out - J (frames >= k)."""
    d = (out - J)[:, k:, 0]
    x = torch.as_tensor(J[:, k:] + d[:, :, None], dtype=torch.float32)
    depth = np.maximum(push_radii(c.margin) - sdf(x).numpy(), 0.0)
    d0 = np.concatenate([np.zeros_like(d[:, :1]), d], 1)
    return float((depth ** 2).sum() + c.weight * (d ** 2).sum() + c.velocity * (np.diff(d0, axis=1) ** 2).sum()
                 + c.acceleration * (np.diff(d0, 2, axis=1) ** 2).sum())


def test_push_out_minimises_its_objective():
    sdf, k = SceneSDF(box_room()), 4
    J = _walk_into_box(k=k).astype(np.float64)
    out = push_out(J, sdf, fixed=k)
    best = _objective(J, out, sdf, k)
    assert best < 0.2 * _objective(J, J, sdf, k)
    for scale in (0.8, 0.95, 1.05, 1.25):  # the solution is a minimum along its own direction
        assert best <= _objective(J, J + scale * (out - J), sdf, k) + 1e-9
    # and against a constant extra offset in each direction over the frames after the seam
    for axis in range(3):
        for sign in (-1, 1):
            moved = out.copy()
            moved[:, k:, :, axis] += sign * 0.01 * np.linspace(0, 1, J.shape[1] - k)[None, :, None]
            assert best <= _objective(J, moved, sdf, k) + 1e-9


def test_planted_feet_stay_where_they_stood_after_push_out_and_foot_cleanup():
    sdf, k = SceneSDF(box_room()), 4
    J = _walk_into_box(k=k)  # the feet skate with the body into the box
    lengths = bone_lengths_of(J[0, 0])
    out = clean_feet(push_out(J, sdf, fixed=k), lengths, FPS, fixed=k)
    legs = [j for leg in LEG_CHAINS for j in leg[1:]]  # the straight test legs re-bend to reach the locks
    upper = [j for j in range(24) if j not in legs]
    assert _depth(sdf, out)[..., upper].max() < 0.015
    for hip, knee, ankle, toe in LEG_CHAINS:  # locked where the context stood them
        np.testing.assert_allclose(out[0, k:, ankle, :2], np.broadcast_to(J[0, k - 1, ankle, :2], (36, 2)), atol=5e-3)


def _thin_wall() -> OccupancyGrid:
    """Floor (z < 0) plus a 10 cm wall x in [1.0, 1.1] across the grid, 2 cm voxels."""
    origin = np.array([0.01, 0.01, -0.09])
    c = origin[:, None] + 0.02 * np.arange(120)[None]
    x, y, z = np.meshgrid(*c, indexing="ij")
    return OccupancyGrid((z < 0) | ((x > 1.0) & (x < 1.1)), origin, 0.02)


def test_hand_reaching_into_a_thin_wall_is_pushed_out_while_the_seam_knee_cannot_be():
    """The demo's drink stop: a knee inside the wall at the seam (the offset is 0 there) and a hand
    going 5 cm into it at the episode's end. A full Gauss-Newton step pushes the hand out and leaves
    only the knee active; the next step, held by nothing else, pulled the body back in (the
    iterations ping-ponged and ended on the pulled-back one). The damped steps keep the hand out."""
    sdf, k, T = SceneSDF(_thin_wall()), 2, 16
    J = standing_body(T)
    J[..., 1] += 1.0
    J[..., 0] += 0.75
    hand, knee = JOINT_INDEX["left_index1"], JOINT_INDEX["left_knee"]
    r = push_radii()
    J[0, :, hand] = np.c_[1.0 - r[hand] + np.r_[-0.05, -0.05, np.linspace(-0.05, 0.05, T - 2)], np.full(T, 1.0),
                          np.full(T, 0.8)]
    J[0, :, knee, 0] = 1.0 - r[knee] + np.r_[0.04, 0.04, 0.04, 0.02, np.full(T - 4, -0.05)]
    assert _depth(sdf, J)[0, -4:, hand].min() > 0.035
    out = push_out(J, sdf, fixed=k)
    assert _depth(sdf, out)[0, -4:].max() < 0.005  # the hand is out by the episode's end
    assert _objective(J, out, sdf, k) < 0.5 * _objective(J, J, sdf, k)


def test_bad_input_raises():
    sdf = SceneSDF(box_room())
    with pytest.raises(ValueError, match="joints must be"):
        push_out(np.zeros((10, 24, 3)), sdf, 2)
    with pytest.raises(ValueError, match="fixed"):
        push_out(np.zeros((1, 10, 24, 3)), sdf, 11)
    with pytest.raises(ValueError, match="knot"):
        PushOutConfig(knot=0)
