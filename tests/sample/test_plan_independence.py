"""Issue 34: a plan's motion does not depend on which plans ran before it on the same sampler
(``trumans eval safety`` reuses one EpisodeSampler per room across its plans and perturbations)."""
from __future__ import annotations

import numpy as np
import torch

from trumans.sample.plan import plan_from_dict
from trumans.sample.rollout import sample_plan
from trumans.sample.sampler import EpisodeSampler, SamplerConfig
from trumans.scenes.scene_grids import SceneGrids

from helpers import tiny_checkpoint


def test_a_plan_after_other_plans_on_the_same_sampler_equals_the_plan_alone(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    before = plan_from_dict({"start": [1.8, 1.8], "steps": [{"do": "goto", "to": [0.6, 1.2]},
                                                             {"do": "act", "action": "drink", "seconds": 1.0}]})
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "goto", "to": [1.6, 0.6]},
                                                           {"do": "act", "action": "drink", "seconds": 1.0}]})
    threads = torch.get_num_threads()
    alone = sample_plan(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=3)), scene, wm, plan, seed=4)
    shared = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=3))
    sample_plan(ck, shared, scene, wm, before, seed=9)  # another body, start and seed first
    sample_plan(ck, shared, scene, wm, plan, seed=5)
    after = sample_plan(ck, shared, scene, wm, plan, seed=4)
    assert torch.get_num_threads() == threads
    assert after.episodes == alone.episodes and after.joints.shape == alone.joints.shape
    np.testing.assert_array_equal(after.joints, alone.joints)
    np.testing.assert_array_equal(after.labels, alone.labels)
