"""trumans.sample.sampler / trumans.sample.rollout mechanics on a tiny untrained generator: masks honoured at the
episode ends, bone lengths kept, precomputed conditions equal to the naive sampler, streaming
order and the incremental latency schedule. (Motion quality is the synthesis benchmark's job.)"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.sample.cleanup.attach_pelvis import attach_pinned_pelvis
from trumans.sample.controller import Phase
from trumans.sample.plan import plan_from_dict
from trumans.sample.rollout import INCREMENTAL_SCHEDULE, sample_plan, start_context, stream
from trumans.sample.sampler import EpisodeSampler, Goal, SamplerConfig, bone_lengths_of, project_bones
from trumans.scenes.scene_grids import SceneGrids
from trumans.skeleton import JOINT_INDEX, REST_JOINTS

from helpers import SAMPLE_VOCAB, standing_body, tiny_checkpoint


def test_project_bones_keeps_lengths_and_directions():
    rng = np.random.default_rng(0)
    lengths = bone_lengths_of(REST_JOINTS.astype(np.float64))
    noisy = REST_JOINTS[None] + rng.normal(0, 0.03, (5, 24, 3))
    out = project_bones(noisy, lengths)
    np.testing.assert_allclose(bone_lengths_of(out.astype(np.float64)), np.broadcast_to(lengths, (5, 24)), atol=1e-5)
    np.testing.assert_allclose(out[:, 0], noisy[:, 0], atol=1e-6)  # the root stays
    np.testing.assert_allclose(project_bones(REST_JOINTS, lengths), REST_JOINTS, atol=1e-5)  # a fixed point


def test_episode_honours_masks_and_context(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    sampler = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=5))
    ctx = start_context(ck, np.array([1.0, 1.0]), 0.3, batch=2)
    labels = np.zeros((2, 16, len(SAMPLE_VOCAB)), np.float32)
    goals = [Goal((1.8, 1.2)), Goal((1.5, 1.0, 0.9), "right_wrist", 9)]
    out = sampler.episode(ctx, labels, goals, generator=torch.Generator().manual_seed(0))
    assert out.shape == (2, 16, 24, 3) and np.isfinite(out).all()
    np.testing.assert_allclose(out[:, :2], ctx, atol=1e-5)  # M_trans: the context frames exactly
    np.testing.assert_allclose(out[0, -1, JOINT_INDEX["pelvis"], :2], [1.8, 1.2], atol=1e-4)  # M_goal pelvis xy
    np.testing.assert_allclose(out[1, 9, JOINT_INDEX["right_wrist"]], [1.5, 1.0, 0.9], atol=1e-4)  # hand goal
    # the first cleanup step puts the pinned pelvis back on the body: same offset from the hips as one frame before
    att = attach_pinned_pelvis(sampler.episode(ctx, labels, goals, generator=torch.Generator().manual_seed(0)),
                               np.array([g.joint == "pelvis" for g in goals]))
    hips = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]
    off = att[0, :, 0, :2] - att[0][:, hips, :2].mean(1)
    np.testing.assert_allclose(off[-1], off[-2], atol=1e-5)
    np.testing.assert_allclose(att[0, :-1], out[0, :-1], atol=1e-6)  # nothing else changes


def test_precomputed_conditions_match_naive(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint(1)
    ctx = start_context(ck, np.array([1.0, 1.0]), 0.0)
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    labels[:, :, 1] = 1.5
    outs = [EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=4, naive=n)).episode(
        ctx, labels, [Goal((1.5, 1.0))], generator=torch.Generator().manual_seed(3)) for n in (False, True)]
    np.testing.assert_allclose(outs[0], outs[1], atol=1e-5)


def test_sample_plan_runs_to_the_end_and_keeps_bones(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    sampler = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=3, overlap=0))
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "goto", "to": [1.6, 0.6]},
                                                           {"do": "act", "action": "drink", "seconds": 1.0}]})
    res = sample_plan(ck, sampler, scene, wm, plan, num_samples=2, seed=0)
    B, T = res.joints.shape[:2]
    assert B == 2 and T == 2 + 14 * res.episodes and res.labels.shape == (2, T, len(SAMPLE_VOCAB))
    cv = np.std(bone_lengths_of(res.joints[0].astype(np.float64))[:, 1:], 0)
    assert cv.max() < 1e-4  # bone lengths kept over the whole rollout
    assert res.episode_starts == [14 * e for e in range(res.episodes)]
    # every episode's goal is recorded at its last frame
    assert len(res.goals) == 2 * res.episodes
    assert all(f == s + 15 for (f, b, j, p), s in zip(res.goals[::2], res.episode_starts) if j == "pelvis")


def test_overlapping_episodes_commit_less_and_follow_the_uncommitted_frames(open_room, monkeypatch):
    """SamplerConfig.overlap = D: every episode but the last commits L - k - D new frames, the next one
    starts there and is sampled following the D frames the earlier episode made (cleaned) without
    committing them, with the crossfade's weights, and keeping the earlier episode's goals due on them."""
    import trumans.sample.rollout as rollout
    from trumans.sample.cleanup.seam import crossfade_weights

    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "goto", "to": [1.6, 0.6]},
                                                           {"do": "act", "action": "drink", "seconds": 1.0}]})
    calls, cleaned = [], []
    episode, cleanup = EpisodeSampler.episode, rollout.run_cleanup
    def made(self, context, labels, goals, **kw):
        out = episode(self, context, labels, goals, **kw)
        calls.append((goals, kw, out.copy()))
        return out
    monkeypatch.setattr(EpisodeSampler, "episode", made)

    def watched(bodies, config, observe=None):
        assert config.seam.enabled is (not cleaned)  # the overlap replaces the seam blend
        cleaned.append(cleanup(bodies, config, observe))
        return cleaned[-1]
    monkeypatch.setattr(rollout, "run_cleanup", watched)
    D, k = 3, 2
    res = sample_plan(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=3, overlap=D)), scene, wm, plan, seed=0)
    n = 14 - D
    assert res.episode_starts == [n * e for e in range(res.episodes)] and len(calls) == res.episodes >= 2
    assert res.joints.shape[1] == k + n * (res.episodes - 1) + 14  # the last episode commits all 14
    assert "lead" not in calls[0][1]  # the first episode: nothing to follow
    for e in range(1, res.episodes):
        goals, kw, raw = calls[e]
        np.testing.assert_array_equal(kw["lead"], cleaned[e - 1][:, k + n:])  # the earlier one's uncommitted frames
        np.testing.assert_allclose(kw["lead_weight"], 1.0 - crossfade_weights(D))
        prev = calls[e - 1][0][0]
        if prev.joint == "pelvis":  # its pelvis goal is due at its last frame: this episode's frame k + D - 1
            (carried,), = kw["carried"]
            assert carried.frame == k + D - 1 and carried.point == prev.point
        s = k + n * e  # what is committed: the cleaned episode
        np.testing.assert_array_equal(res.joints[:, s:s + n], cleaned[e][:, k:k + n])
    assert all(f < res.joints.shape[1] for f, *_ in res.goals)
    cv = np.std(bone_lengths_of(res.joints[0].astype(np.float64))[:, 1:], 0)
    assert cv.max() < 1e-4  # the overlapped frames keep the body's bones too
    with pytest.raises(ValueError, match="overlap 14 leaves no new frame"):
        sample_plan(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=3, overlap=14)), scene, wm, plan)
    with pytest.raises(ValueError, match="overlap must be >= 0"):
        SamplerConfig(overlap=-1)


def test_crossfade_weights():
    from trumans.sample.cleanup.seam import crossfade_weights

    w = crossfade_weights(3)
    assert np.all(np.diff(w) > 0) and 0 < w[0] < 0.2 and 0.8 < w[-1] < 1 and w[1] == pytest.approx(0.5)
    assert crossfade_weights(0).shape == (0,)
    with pytest.raises(ValueError, match="D must be"):
        crossfade_weights(-1)


def test_an_episode_follows_its_lead_frames_by_their_weights(open_room):
    """EpisodeSampler.episode(lead=...): weight 1 gives the lead frames exactly, weight 0 the episode
    without a lead (the same seed), and the frames after a followed lead change."""
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    s = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=4, overlap=0))
    ctx = np.repeat(standing_body(1)[:, :1], 2, 1).astype(np.float32)
    ctx[..., :2] += 1.0
    labels = np.zeros((1, 16, len(ck.vocabulary)), np.float32)
    goal = [Goal((1.5, 1.0))]
    run = lambda **kw: s.episode(ctx, labels, goal, generator=torch.Generator().manual_seed(0), **kw)  # noqa: E731
    base = run()
    lead = base[:, 2:5].copy()
    lead[..., 1] += 0.3  # the lead: 30 cm to the side of what the network makes
    np.testing.assert_allclose(run(lead=lead, lead_weight=np.zeros(3)), base, atol=1e-5)
    hard = run(lead=lead, lead_weight=np.ones(3))
    np.testing.assert_allclose(hard[:, 2:5], lead, atol=1e-4)
    assert np.abs(hard[:, 5:] - base[:, 5:]).max() > 1e-3
    with pytest.raises(ValueError, match="lead_weight"):
        run(lead=lead, lead_weight=np.full(3, 2.0))
    with pytest.raises(ValueError, match="lead must be"):
        run(lead=lead[..., :2], lead_weight=np.ones(3))


def test_stream_incremental_schedule_and_new_plans(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint()
    sampler = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=2))
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "goto", "to": [2.0, 0.6]}]})
    gen = stream(ck, sampler, scene, wm, plan, seed=0)
    sizes = [len(next(gen)) for _ in range(5)]
    assert sizes == [*INCREMENTAL_SCHEDULE, 14, 14]  # 2, 4, 8 frames, then full episodes
    chunk = gen.send(plan_from_dict({"steps": [{"do": "goto", "to": [0.8, 1.6]}]}))  # a new control signal
    assert len(chunk) == INCREMENTAL_SCHEDULE[0]  # reacts at once: the schedule restarts
    assert [len(next(gen)) for _ in range(3)] == [*INCREMENTAL_SCHEDULE[1:], 14]
    with pytest.raises(ValueError, match="schedule"):
        next(stream(ck, sampler, scene, wm, plan, schedule=(0,)))


def test_external_mesh_as_scene_is_cached_and_sampled(tmp_path):
    import trimesh

    from trumans.sample.scene_input import load_sample_scene

    floor = trimesh.creation.box((4.0, 3.0, 0.1))
    floor.apply_translation([2.0, 1.5, -0.05])
    block = trimesh.creation.box((0.6, 0.6, 0.8))
    block.apply_translation([2.0, 1.5, 0.4])
    room = trimesh.util.concatenate([floor, block])
    path = tmp_path / "scan.obj"
    room.export(path)
    sc = load_sample_scene(str(path), voxel=0.05)
    assert (tmp_path / "scan.occupancy" / "occupancy.npz").is_file()  # cached beside the mesh
    assert not sc.walkmap.query(np.array([[2.0, 1.5]]))[0] and sc.walkmap.query(np.array([[0.8, 1.5]]))[0]
    ck = tiny_checkpoint()
    sampler = EpisodeSampler(ck, sc.grids, SamplerConfig(steps=2))
    plan = plan_from_dict({"start": [0.7, 0.7], "steps": [{"do": "goto", "to": [3.3, 2.3]}]})
    res = sample_plan(ck, sampler, sc.scene, sc.walkmap, plan, seed=0)
    assert res.joints.shape[1] > 16 and np.isfinite(res.joints).all()
    # the y-up file of the same room, read with up='y', gives the same occupancy
    yup = room.copy()
    yup.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
    yup.export(tmp_path / "scan_y.obj")
    sy = load_sample_scene(str(tmp_path / "scan_y.obj"), voxel=0.05, up="y")
    assert sy.occupancy.grid.shape == sc.occupancy.grid.shape
    assert (sy.occupancy.grid != sc.occupancy.grid).mean() < 0.01
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_sample_scene(str(tmp_path / "nothing.obj"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match="no scene.json"):
        load_sample_scene(str(tmp_path / "empty"))


def test_goal_guidance_pulls_the_body_onto_its_goal(open_room):
    scene, occ, wm = open_room
    ck = tiny_checkpoint(2)
    ctx = start_context(ck, np.array([1.0, 1.0]), 0.0)
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    goal = Goal((1.9, 1.3))
    hips = [JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]]
    errs = []
    for g in (0.0, 20.0):
        s = EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(steps=6, goal_guidance=g, goal_iters=3))
        out = s.episode(ctx, labels, [goal], generator=torch.Generator().manual_seed(0))
        errs.append(np.linalg.norm(out[0, -1, hips, :2].mean(0) - goal.point))
        np.testing.assert_allclose(out[0, :2], ctx[0], atol=1e-5)  # the context stays exact
    assert errs[1] < 0.7 * errs[0], errs  # an untrained net: guidance alone must still pull it closer
    with pytest.raises(ValueError, match="goal_iters"):
        SamplerConfig(goal_iters=0)


def test_labels_follow_the_checkpoints_progress_indicator(open_room):
    """A model trained without the progress indicator (the ablation) is sampled with 0/1 labels, as trained."""
    scene, occ, wm = open_room
    ctx = start_context(tiny_checkpoint(), np.array([1.0, 1.0]), 0.3, batch=1)
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    labels[0, 4:, 1] = 1.0 + np.linspace(0.0, 1.0, 12)
    goals = [Goal((1.8, 1.2))]
    with_progress = EpisodeSampler(tiny_checkpoint(), SceneGrids(occ)).condition(ctx, labels, goals)
    ck = tiny_checkpoint()
    ck.extra["progress_indicator"] = False
    plain = EpisodeSampler(ck, SceneGrids(occ)).condition(ctx, labels, goals)
    np.testing.assert_allclose(with_progress.actions, labels)
    np.testing.assert_array_equal(plain.actions, (labels > 0).astype(np.float32))
