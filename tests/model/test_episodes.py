"""Episodes: canonical frame, round trips, feature layout, normalisation, masks."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.model.episodes import FeatureLayout, Normalizer, canonical_frame, canonicalize, episode_starts, uncanonicalize
from trumans.model.masks import HAND_JOINTS, MaskSampler, joint_goal_mask, pelvis_goal_mask, transition_mask
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, yaw_matrix
from trumans.skeleton import forward_kinematics, heading


def _motion(rng, B=3, L=16):
    aa = rng.normal(0, 0.2, (B, L, 24, 3))
    aa[..., 0, :] = 0
    aa[..., 0, 2] = rng.uniform(-np.pi, np.pi, (B, 1))
    R = axis_angle_to_matrix(aa)
    root = np.concatenate([rng.uniform(-3, 3, (B, L, 2)), np.full((B, L, 1), 0.9)], -1)
    joints, _ = forward_kinematics(R, root)
    return joints, matrix_to_6d(R)


def test_canonical_frame_properties_and_round_trip() -> None:
    rng = np.random.default_rng(0)
    joints, rot6 = _motion(rng)
    origin, yaw = canonical_frame(joints)
    assert origin.shape == (3, 3) and yaw.shape == (3,) and np.all(origin[:, 2] == 0)
    cj, cr = canonicalize(joints, origin, yaw, rotations=rot6)
    assert np.allclose(cj[:, 0, 0, :2], 0, atol=1e-5)  # first pelvis at x = y = 0
    assert np.allclose(cj[:, 0, 0, 2], joints[:, 0, 0, 2], atol=1e-5)  # height kept
    assert np.allclose(heading(cj[:, 0]), 0, atol=1e-5)  # facing +x
    # rotations: FK of the canonical rotations reproduces the canonical joints
    from trumans.rotations import sixd_to_matrix
    fk, _ = forward_kinematics(sixd_to_matrix(cr.astype(np.float64)), cj[..., 0, :].astype(np.float64))
    assert np.allclose(fk, cj, atol=1e-4)
    wj, wr = uncanonicalize(cj, origin, yaw, rotations=cr)
    assert np.allclose(wj, joints, atol=1e-5) and np.allclose(wr, rot6, atol=1e-5)


def test_canonical_features_invariant_to_world_motion() -> None:
    rng = np.random.default_rng(1)
    joints, _ = _motion(rng, B=1)
    R = yaw_matrix(1.1)
    moved = joints @ R.T + np.array([2.0, -1.0, 0.0])
    a = canonicalize(joints, *canonical_frame(joints))
    b = canonicalize(moved, *canonical_frame(moved))
    assert np.allclose(a, b, atol=1e-5)


def test_bad_shapes() -> None:
    with pytest.raises(ValueError, match=r"\(\.\.\., L, 24, 3\)"):
        canonical_frame(np.zeros((16, 23, 3)))
    with pytest.raises(ValueError, match="origin"):
        canonicalize(np.zeros((2, 16, 24, 3)), np.zeros(3), np.zeros(2))


def test_episode_starts() -> None:
    assert episode_starts(40, 16, 4).tolist() == [0, 4, 8, 12, 16, 20, 24]
    assert episode_starts(15, 16, 1).size == 0
    with pytest.raises(ValueError):
        episode_starts(40, 16, 0)


def test_feature_layout_pack_unpack() -> None:
    rng = np.random.default_rng(2)
    j, r = rng.normal(size=(2, 16, 24, 3)), rng.normal(size=(2, 16, 24, 6))
    lay = FeatureLayout()
    assert lay.dim == 72 and lay.position_index("pelvis", (0, 1)) == [0, 1] and lay.position_index(21) == [63, 64, 65]
    f = lay.pack(j)
    assert f.shape == (2, 16, 72) and np.allclose(lay.unpack(f)[0], j, atol=1e-6)
    lr = FeatureLayout(rotations=True)
    f = lr.pack(j, r)
    jj, rr = lr.unpack(f)
    assert f.shape == (2, 16, 216) and np.allclose(jj, j, atol=1e-6) and np.allclose(rr, r, atol=1e-6)
    with pytest.raises(ValueError, match="rotations"):
        lr.pack(j)


def test_normalizer_round_trip() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(5, 2, (100, 16, 4)).astype(np.float32)
    x[..., 3] = 1.0  # constant feature: std floored, no division by zero
    n = Normalizer.fit(x)
    z = n.normalize(x)
    assert np.allclose(z[..., :3].reshape(-1, 3).mean(0), 0, atol=1e-4) and np.allclose(z[..., :3].reshape(-1, 3).std(0), 1, atol=1e-3)
    assert np.isfinite(z).all()
    assert np.allclose(n.denormalize(z), x, atol=1e-4)
    t = torch.from_numpy(x)
    assert torch.allclose(Normalizer.from_state_dict(n.state_dict()).normalize(t), torch.from_numpy(z), atol=1e-5)


def test_masks() -> None:
    lay = FeatureLayout()
    m = transition_mask(16, lay, 2)
    assert m[:2].all() and not m[2:].any()
    g = pelvis_goal_mask(16, lay)
    assert g.sum() == 2 and g[15, 0] and g[15, 1] and not g[15, 2]
    h = joint_goal_mask(16, lay, "right_wrist", 9)
    assert h.sum() == 3 and h[9, 63:66].all()
    with pytest.raises(ValueError):
        transition_mask(16, lay, 17)


def test_mask_sampler_statistics() -> None:
    lay = FeatureLayout()
    s = MaskSampler(16, lay, k=2, p_trans=0.7, p_goal_pelvis=0.5, p_goal_hand=0.3)
    m = s(20000, torch.Generator().manual_seed(0))
    assert m.shape == (20000, 16, 72) and m.dtype == torch.bool
    trans = m[:, :2].all(dim=(1, 2))
    assert abs(trans.float().mean().item() - 0.7) < 0.02
    pelvis = m[:, 15, 0] & m[:, 15, 1] & ~m[:, 15, 2]
    assert abs(pelvis.float().mean().item() - 0.5) < 0.02
    hand_cols = torch.tensor([c for j in HAND_JOINTS for c in lay.position_index(j)])
    hand = m[:, 2:, :][:, :, hand_cols].any(dim=(1, 2))
    assert abs(hand.float().mean().item() - 0.3) < 0.02
    # a hand goal is exactly 3 entries in one frame >= k
    per = m[hand][:, 2:].sum(dim=(1, 2))
    assert (per == 3 + 2 * pelvis[hand].long()).all()
    with pytest.raises(ValueError, match="probability"):
        MaskSampler(16, lay, p_trans=1.5)
