"""Seated pelvis height guidance (trumans.sample.guidance.seat + Goal.pelvis_z in trumans.sample.sampler)."""
from __future__ import annotations

import numpy as np
import torch

from trumans.sample.controller import Phase
from trumans.sample.rollout import start_context
from trumans.sample.sampler import EpisodeSampler, Goal, SamplerConfig
from trumans.sample.guidance.seat import seated_heights
from trumans.scenes.scene_grids import SceneGrids
from trumans.skeleton import JOINT_INDEX

from helpers import SAMPLE_VOCAB, tiny_checkpoint


def test_seated_heights_follow_the_sit_phases():
    phases = [Phase("walk", ("walk",)), Phase("sit", ("sit",), 20, info={"seat_height": 0.45})]
    phase_of = np.array([-1, -1, 0, 0, 1, 1, 1, -1])
    out = seated_heights(phase_of, phases, 0.1, k=2)
    assert [f for f, _ in out] == [4, 5, 6]
    np.testing.assert_allclose([z for _, z in out], 0.55)
    assert seated_heights(np.array([1, 1, 0]), phases, 0.1, k=2) == ()  # context frames are not targeted


def test_guidance_pulls_the_seated_pelvis_to_the_seat_height(open_room):
    _, occ, _ = open_room
    ck = tiny_checkpoint(2)
    ctx = start_context(ck, np.array([1.0, 1.0]), 0.0)
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    target = 0.5  # m, well under the standing pelvis (~0.95 m)
    frames = tuple((f, target) for f in range(8, 16))
    pelvis = JOINT_INDEX["pelvis"]
    errs = []
    for z in ((), frames):
        s = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=6, goal_guidance=20.0, goal_iters=3))
        out = s.episode(ctx, labels, [Goal((1.0, 1.0), pelvis_z=z)], generator=torch.Generator().manual_seed(0))
        errs.append(np.abs(out[0, 8:15, pelvis, 2] - target).mean())  # frame 15: the pelvis is re-attached
    assert errs[1] < 0.5 * errs[0], errs


def test_sit_offset_rests_the_seat_joints_on_the_seat():
    """The data's convention (trumans.synth.activity_seats): the seated body is raised until the
    skin of pelvis and hips touches the seat, well above ``seat_clearance`` alone."""
    from trumans.contacts.rule import JOINT_RADIUS
    from trumans.skeleton import SEAT, forward_kinematics, rest_offsets
    from trumans.synth.posture import seat_clearance, seated_state

    from trumans.body import sit_offset

    for scale in (0.9, 1.0, 1.1):
        off = rest_offsets(scale)
        pose, _ = forward_kinematics(np.broadcast_to(np.eye(3), (1, 24, 3, 3)), np.zeros((1, 3)), off)
        h = sit_offset(pose[0])
        assert 0.14 * scale < h < 0.20 * scale and h > seat_clearance(off) + 0.05, (scale, h)
        rot, root = seated_state(off, np.array([1.0, 2.0, 0.5]), 0.7, np.array([1.3, 2.2]))
        P, _ = forward_kinematics(rot[None], (root + [0.0, 0.0, h - (root[2] - 0.5)])[None], off)
        skin = P[0, list(SEAT), 2] - JOINT_RADIUS[list(SEAT)] - 0.5
        assert abs(skin.min()) < 1e-6  # resting on the seat: not floating, not sinking
