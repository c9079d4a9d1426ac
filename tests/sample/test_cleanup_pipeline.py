"""The generator's post-network corrections as one pipeline (trumans.sample.cleanup.pipeline): the
documented order, one config reaching every step, disabled steps skipped."""
from __future__ import annotations

import re
from dataclasses import fields, replace

import numpy as np
import pytest
import torch

import trumans.sample.cleanup.pipeline as pipeline
from trumans.sample.cleanup.bones import bone_lengths_of
from trumans.sample.cleanup.pipeline import STEPS, CleanupConfig, EpisodeBodies, run_cleanup
from trumans.sample.cleanup.scene_pushout import PushOutConfig
from trumans.sample.cleanup.seam import SeamConfig, blend_seam
from trumans.sample.cleanup.support_lift import SupportLiftConfig
from trumans.scenes.sdf import SceneSDF
from trumans.skeleton import JOINT_INDEX

from helpers import SAMPLE_VOCAB, box_room, standing_body

K, L = 2, 16
PELVIS = JOINT_INDEX["pelvis"]


@pytest.fixture(scope="module")
def sdf():
    return SceneSDF(box_room())


def _episode(sdf: SceneSDF | None) -> EpisodeBodies:
    """A standing body drifting into the box (x = 1.0 m face) with noisy bones, a jump at the seam,
    the new frames 3 cm into the floor and the last pelvis torn 5 cm off the hips: every step has
    something to do (the reach only on frames 10-15 of the right arm)."""
    rng = np.random.default_rng(0)
    body = standing_body(L)[0]  # (L, 24, 3) on the floor at x = y = 0
    lengths = bone_lengths_of(body[0].astype(np.float64))
    J = body + np.array([0.75, 1.0, 0.0])
    J[:, :, 0] += np.linspace(0.0, 0.2, L)[:, None]  # walks into the box
    context = J[None, :K].astype(np.float32).copy()
    J[K:] += rng.normal(0.0, 0.01, J[K:].shape)  # the network's bones
    J[K:] += np.array([0.03, -0.02, -0.03])  # a jump at the seam, and under the floor
    J[-1, PELVIS, :2] += 0.05  # the pinned pelvis
    labels = np.zeros((1, L, len(SAMPLE_VOCAB)), np.float32)
    labels[..., SAMPLE_VOCAB.index("stand")] = 1.5
    weight = np.zeros((1, L, 2))
    weight[0, 10:, 1] = np.linspace(0.2, 1.0, L - 10)
    target = np.zeros((1, L, 2, 3))
    target[0, :, 1] = J[-1, JOINT_INDEX["right_wrist"]] + np.array([0.1, -0.1, 0.1])
    return EpisodeBodies(J[None].astype(np.float32), context, lengths, labels, tuple(SAMPLE_VOCAB), 10.0,
                         np.array([True]), weight, target, sdf)


def _trace(episode: EpisodeBodies, config: CleanupConfig) -> tuple[np.ndarray, list[tuple[str, np.ndarray]]]:
    seen: list[tuple[str, np.ndarray]] = []
    out = run_cleanup(episode, config, observe=lambda name, j: seen.append((name, np.array(j, copy=True))))
    return out, seen


def test_steps_run_in_the_documented_order(sdf):
    documented = re.findall(r"^\d+\. ``(\w+)``", pipeline.__doc__, re.MULTILINE)
    names = [s.name for s in STEPS]
    assert documented == names == [f.name for f in fields(CleanupConfig)]
    assert names == ["attach_pelvis", "seam", "bone_projection", "support_lift", "scene_pushout", "containment",
                     "seat_settle", "arm_pushout", "foot", "reach", "swept_guard"]
    _, seen = _trace(_episode(sdf), CleanupConfig())
    assert [name for name, _ in seen] == names


def test_every_step_changes_this_episode_and_keeps_its_shape(sdf):
    ep = _episode(sdf)
    out, seen = _trace(ep, CleanupConfig())
    before = [ep.joints] + [j for _, j in seen[:-1]]
    changed = {name: not np.array_equal(a, b) for (name, b), a in zip(seen, before)}
    assert all(changed[n] for n in ("attach_pelvis", "seam", "bone_projection", "support_lift", "scene_pushout",
                                    "foot", "reach")), changed
    assert out.shape == ep.joints.shape and np.isfinite(out).all()
    np.testing.assert_allclose(bone_lengths_of(out[0, K:].astype(np.float64)),
                               np.broadcast_to(ep.lengths, (L - K, 24)), atol=1e-4)  # every step after the projection keeps them


@pytest.mark.parametrize("name", [s.name for s in STEPS])
def test_a_disabled_step_is_skipped_and_changes_nothing(sdf, name):
    ep = _episode(sdf)
    _, full = _trace(ep, CleanupConfig())
    off, seen = _trace(ep, CleanupConfig().switched(**{name: False}))
    i = [n for n, _ in seen].index(name)
    before = ep.joints if i == 0 else seen[i - 1][1]
    np.testing.assert_array_equal(seen[i][1], before)  # the step did nothing
    for (n, a), (_, b) in zip(full[:i], seen[:i]):  # the steps before it are as in the full pipeline
        np.testing.assert_array_equal(a, b, err_msg=n)
    # and the rest run on what the steps before it left: as if it were not in the pipeline
    rest = replace(ep, joints=before)
    later = replace(CleanupConfig(), **{s.name: replace(getattr(CleanupConfig(), s.name), enabled=False)
                                        for s in STEPS[:i + 1]})
    np.testing.assert_array_equal(off, run_cleanup(rest, later))


def test_all_steps_off_return_the_network_output(sdf):
    ep = _episode(sdf)
    none = CleanupConfig().switched(**{s.name: False for s in STEPS})
    np.testing.assert_array_equal(run_cleanup(ep, none), ep.joints)


def test_a_step_parameter_in_the_config_reaches_the_step(sdf):
    ep = _episode(sdf)
    names = [s.name for s in STEPS]
    seam = names.index("seam")
    for frames in (3, 6):
        _, seen = _trace(ep, CleanupConfig(seam=SeamConfig(frames=frames)))
        expect = np.array(seen[seam - 1][1], copy=True)
        expect[:, K:] = blend_seam(ep.context, expect[:, K:], frames)
        np.testing.assert_array_equal(seen[seam][1], expect)
    # the push-out's margin: a wider one leaves the new frames farther from the box
    push = names.index("scene_pushout")
    clear = []
    for margin in (0.01, 0.06):
        _, seen = _trace(ep, CleanupConfig(scene_pushout=PushOutConfig(margin=margin)))
        clear.append(float(sdf(torch.as_tensor(seen[push][1][0, -1], dtype=torch.float32)).min()))
    assert clear[1] > clear[0] + 0.02, clear
    # the support lift's seated actions: with 'stand' seated the feet carry nothing, no lift
    lift = names.index("support_lift")
    _, seen = _trace(ep, CleanupConfig(support_lift=SupportLiftConfig(seated_actions=("stand",))))
    np.testing.assert_array_equal(seen[lift][1], seen[lift - 1][1])


def test_steps_without_a_scene_or_a_reach_leave_the_body():
    ep = replace(_episode(None), reach_weight=np.zeros((1, L, 2)))
    only = {"scene_pushout", "arm_pushout", "reach"}
    config = CleanupConfig().switched(**{s.name: s.name in only for s in STEPS})
    np.testing.assert_array_equal(run_cleanup(ep, config), ep.joints)


def test_switched_and_episode_errors_name_the_problem(sdf):
    with pytest.raises(ValueError, match="unknown cleanup steps"):
        CleanupConfig().switched(feet=False)
    with pytest.raises(ValueError, match="seam frames"):
        SeamConfig(frames=-1)
    ep = _episode(sdf)
    with pytest.raises(ValueError, match="reach_weight"):
        replace(ep, reach_weight=np.zeros((1, L)))
    with pytest.raises(ValueError, match="context"):
        replace(ep, context=ep.context[:, :1])
