"""Scene-penetration guidance (trumans.sample.guidance.penetration and its use in trumans.sample.sampler)."""
from __future__ import annotations

import numpy as np
import torch

from trumans.sample.guidance import GuidanceConfig
from trumans.sample.guidance.penetration import SceneSDF, penetration_loss
from trumans.sample.rollout import start_context
from trumans.sample.sampler import EpisodeSampler, Goal, SamplerConfig
from trumans.scenes.scene_grids import SceneGrids
from trumans.contacts.rule import JOINT_CORE_RADIUS

from helpers import SAMPLE_VOCAB, box_room, tiny_checkpoint


def test_sdf_gradient_is_the_outward_normal_and_values_agree():
    sdf = SceneSDF(box_room())
    pts = torch.tensor([[0.8, 1.0, 0.5], [1.05, 1.0, 0.5], [1.2, 0.5, 0.5], [1.2, 1.0, 1.2]])  # front, inside, side, top
    d, g = sdf.value_and_gradient(pts)
    np.testing.assert_allclose(d.numpy(), sdf(pts).numpy(), atol=1e-6)
    np.testing.assert_allclose(g.numpy(), [[-1, 0, 0], [-1, 0, 0], [0, -1, 0], [0, 0, 1]], atol=0.05)
    assert g.shape == pts.shape and sdf.value_and_gradient(pts[None])[1].shape == (1, 4, 3)


def test_sdf_is_signed_distance_and_ignores_the_floor():
    sdf = SceneSDF(box_room())
    pts = torch.tensor([[0.7, 1.0, 0.5], [1.2, 1.0, 0.5], [1.2, 1.0, 1.3], [0.5, 0.3, 0.05]])
    d = sdf(pts).numpy()
    np.testing.assert_allclose(d[0], 0.3, atol=0.03)  # 30 cm in front of the box
    assert -0.25 < d[1] < -0.15  # 20 cm deep inside
    np.testing.assert_allclose(d[2], 0.3, atol=0.03)  # above it
    assert d[3] > 0.3  # near the floor but far from the box: the floor is not an obstacle here


def test_descending_the_loss_pushes_a_pose_out_of_the_box():
    sdf = SceneSDF(box_room())
    j = torch.full((24, 3), 0.0)
    j[:, 0], j[:, 1], j[:, 2] = 1.05, 1.0, torch.linspace(0.1, 1.5, 24)  # a body standing 5 cm into the box
    j.requires_grad_(True)
    before = penetration_loss(sdf, j).item()
    opt = torch.optim.SGD([j], lr=0.5)
    for _ in range(50):
        opt.zero_grad()
        penetration_loss(sdf, j).backward()
        opt.step()
    assert before > 0.01 and penetration_loss(sdf, j).item() < 0.05 * before
    pen = np.maximum(JOINT_CORE_RADIUS - sdf(j.detach()).numpy(), 0)
    assert pen.max() < 0.02


def test_guided_episode_penetrates_less():
    occ = box_room()
    ck = tiny_checkpoint(3)
    ctx = start_context(ck, np.array([0.9, 1.0]), 0.0)  # facing the box, 10 cm in front of it
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    sdfs, pens = SceneSDF(occ), []
    for on in (False, True):
        s = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=6, goal_guidance=20.0, goal_iters=3,
                                                               guidance=GuidanceConfig().switched(penetration=on)))
        out = s.episode(ctx, labels, [Goal((1.3, 1.0), guide=False)], generator=torch.Generator().manual_seed(0))
        d = sdfs(torch.as_tensor(out[0, 2:], dtype=torch.float32)).numpy()
        pens.append(np.maximum(JOINT_CORE_RADIUS - d, 0).sum())
    assert pens[1] < 0.7 * pens[0], pens
