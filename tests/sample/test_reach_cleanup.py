"""Reach cleanup (trumans.sample.cleanup.reach): the arm onto its hand target, lean, blend, schedule, errors."""
import argparse

import numpy as np
import pytest

from trumans.sample.controller import Controller, Phase
from trumans.sample.cleanup.reach import (ARMS, ReachCleanupConfig, clean_reach, lean_angle, reach_schedule,
                                  release_weights, tilt_limit)
from trumans.sample.sampler import bone_lengths_of
from trumans.sample.sampling_args import add_postprocess_arguments, postprocess_kwargs
from trumans.rotations import rodrigues
from trumans.skeleton import JOINT_INDEX, REST_JOINTS, SUBTREE

from helpers import tiny_checkpoint

SH, EL, WR, IX = ARMS[1]  # right arm
NO_LEAN = ReachCleanupConfig(max_lean=0.0)


def _body(T: int = 1) -> np.ndarray:
    """(1, T, 24, 3) rest body with the right elbow bent 60 degrees downwards (the forearm turned
    about the horizontal forward axis at the elbow), so the arm has a bend plane."""
    J = REST_JOINTS.astype(np.float64).copy()
    fore = SUBTREE[EL][1:]  # wrist, index1
    R = rodrigues(np.array([1.0, 0.0, 0.0]), np.radians(-60.0))
    J[fore] = J[EL] + (J[fore] - J[EL]) @ R.T
    return np.broadcast_to(J, (1, T, 24, 3)).copy()


def _lengths(J: np.ndarray) -> np.ndarray:
    return bone_lengths_of(J[0, 0])


def _one_target(J: np.ndarray, point, w=1.0) -> tuple[np.ndarray, np.ndarray]:
    B, T = J.shape[:2]
    target = np.zeros((B, T, 2, 3))
    weight = np.zeros((B, T, 2))
    target[:, :, 1] = point
    weight[:, :, 1] = w
    return target, weight


def test_short_arm_reaches_target_with_bone_lengths_kept():
    J = _body()
    L = _lengths(J)
    goal = J[0, 0, WR] + np.array([0.15, 0.05, 0.10])  # the wrist ends 19 cm short of this point
    assert np.linalg.norm(goal - J[0, 0, SH]) < L[EL] + L[WR]  # within reach: no lean needed
    out = clean_reach(J, L, *_one_target(J, goal), config=NO_LEAN)
    assert np.linalg.norm(out[0, 0, WR] - goal) < 1e-3
    np.testing.assert_allclose(bone_lengths_of(out[0, 0]), L, atol=1e-9)
    # the shoulder and the rest of the body stay; the elbow stays on the side of its old bend
    keep = [j for j in range(24) if j not in (EL, WR, IX)]
    np.testing.assert_array_equal(out[0, 0, keep], J[0, 0, keep])
    old_bend = J[0, 0, EL] - 0.5 * (J[0, 0, SH] + J[0, 0, WR])
    new_bend = out[0, 0, EL] - 0.5 * (out[0, 0, SH] + out[0, 0, WR])
    assert old_bend @ new_bend > 0
    fore, hand = out[0, 0, WR] - out[0, 0, EL], out[0, 0, IX] - out[0, 0, WR]
    assert fore @ hand / np.linalg.norm(fore) / np.linalg.norm(hand) == pytest.approx(1.0, abs=1e-9)  # along the arm


def test_out_of_reach_without_lean_stretches_along_the_line():
    J = _body()
    L = _lengths(J)
    goal = J[0, 0, SH] + np.array([1.5, -0.6, -0.3])  # 1.6 m from the shoulder, the arm is 0.5 m
    out = clean_reach(J, L, *_one_target(J, goal), config=NO_LEAN)[0, 0]
    s, e, w = out[SH], out[EL], out[WR]
    line = (goal - s) / np.linalg.norm(goal - s)
    # wrist on the shoulder -> target line; the elbow too, up to the 1 mm the solver keeps from full extension
    for p, tol in ((w, 1e-9), (e, 0.02)):
        v = p - s
        assert np.linalg.norm(v - (v @ line) * line) < tol and v @ line > 0
    assert np.linalg.norm(w - s) == pytest.approx(L[EL] + L[WR], abs=2e-3)  # straight, not broken
    np.testing.assert_allclose(bone_lengths_of(out), L, atol=1e-9)


def test_out_of_reach_leans_the_upper_body_within_the_tilt_limit():
    J = _body()
    L = _lengths(J)
    goal = J[0, 0, SH] + np.array([0.55, -0.1, -0.45])  # forward and down: 0.72 m from the shoulder
    cfg = ReachCleanupConfig(max_lean=np.radians(40.0), max_tilt=np.radians(45.0))
    out = clean_reach(J, L, *_one_target(J, goal), config=cfg)[0, 0]
    np.testing.assert_allclose(bone_lengths_of(out), L, atol=1e-9)
    assert np.linalg.norm(out[WR] - goal) < 1e-3  # the lean brought the target within reach
    trunk = out[JOINT_INDEX["neck"]] - out[JOINT_INDEX["pelvis"]]
    tilt = np.degrees(np.arccos(trunk[2] / np.linalg.norm(trunk)))
    assert 5.0 < tilt <= 45.0 + 1e-6
    legs = [JOINT_INDEX[n] for n in ("pelvis", "left_hip", "left_knee", "left_ankle", "right_foot")]
    np.testing.assert_array_equal(out[legs], J[0, 0, legs])  # the lean turns the upper body only
    # a tighter tilt limit leans less and leaves the wrist short, on a straight arm toward the target
    tight = clean_reach(J, L, *_one_target(J, goal), config=ReachCleanupConfig(max_tilt=np.radians(10.0)))[0, 0]
    trunk = tight[JOINT_INDEX["neck"]] - tight[JOINT_INDEX["pelvis"]]
    assert np.degrees(np.arccos(trunk[2] / np.linalg.norm(trunk))) <= 10.0 + 1e-6
    assert np.linalg.norm(tight[WR] - goal) > 0.05
    assert np.linalg.norm(tight[WR] - tight[SH]) == pytest.approx(L[EL] + L[WR], abs=2e-3)


def test_lean_angle_law_of_cosines_and_tilt_limit():
    pivot, shoulder = np.zeros(3), np.array([0.0, 0.0, 0.5])
    target = np.array([0.8, 0.0, 0.5])  # 0.8 m from the shoulder, reach 0.5 m
    theta, axis = lean_angle(pivot, shoulder, target, 0.5, np.pi / 2)
    turned = rodrigues(axis, theta) @ shoulder
    assert np.linalg.norm(turned - target) == pytest.approx(0.5, abs=1e-9)
    assert lean_angle(pivot, shoulder, np.array([0.3, 0.0, 0.5]), 0.5, np.pi / 2)[0] == 0.0  # within reach
    assert lean_angle(pivot, shoulder, target, 0.5, 0.1)[0] == pytest.approx(0.1)  # capped
    up, y = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 1.0, 0.0]])
    np.testing.assert_allclose(tilt_limit(up, y, np.array([0.3]), np.radians(40.0)), [0.3])
    np.testing.assert_allclose(tilt_limit(up, y, np.array([1.2]), np.radians(40.0)), [np.radians(40.0)], atol=1e-4)
    tilted = np.array([[np.sin(0.9), 0.0, np.cos(0.9)]])  # 52 degrees already: no further, but back is fine
    np.testing.assert_allclose(tilt_limit(tilted, y, np.array([0.3]), np.radians(40.0)), [0.0], atol=1e-6)
    np.testing.assert_allclose(tilt_limit(tilted, -y, np.array([0.3]), np.radians(40.0)), [0.3])


def test_blend_keeps_frames_outside_the_window_and_has_no_jump():
    T, fps = 40, 10.0
    J = _body(T)
    L = _lengths(J)
    goal = J[0, 0, WR] + np.array([0.2, 0.0, 0.1])
    phase = Phase("reach", ("reach",), frames=20, hand_goal=goal, hand="right_wrist", step=0)
    w = np.zeros(T)
    w[5:25], _ = reach_schedule(phase, np.arange(20), fps)  # ramps in, 1 at frame 24 (the grasp)
    w[25:] = release_weights(np.arange(1, T - 24), fps)  # fades out after it
    target, weight = _one_target(J, goal)
    weight[0, :, 1] = w
    out = clean_reach(J, L, target, weight, fixed=3)
    free = w == 0
    assert free[:17].all() and free[31:].all() and not free[17:31].any()  # 0.8 s in, 0.6 s out
    np.testing.assert_array_equal(out[0, free], J[0, free])  # untouched bit for bit
    assert np.linalg.norm(out[0, 24, WR] - goal) < 1e-3
    wr = out[0, :, WR]
    step = np.linalg.norm(np.diff(wr, axis=0), axis=1)
    dist = np.linalg.norm(goal - J[0, 0, WR])
    assert step.max() < dist * 1.5 / (0.6 * fps + 1) + 1e-3  # the steeper (release) smoothstep slope: no jump
    acc = np.linalg.norm(np.diff(wr, 2, axis=0), axis=1)
    assert acc.max() < dist * 6 / (0.6 * fps + 1) ** 2 + 1e-3  # smoothstep's largest curvature, edges included
    np.testing.assert_allclose(bone_lengths_of(out[0]), np.broadcast_to(L, (T, 24)), atol=1e-9)
    # the context (frames < fixed) stays even with a weight there
    weight[0, :, 1] = 1.0
    out = clean_reach(J, L, target, weight, fixed=3)
    np.testing.assert_array_equal(out[0, :3], J[0, :3])
    assert np.linalg.norm(out[0, 3:, WR] - goal, axis=1).max() < 1e-3


def test_bad_inputs_raise_clear_errors():
    J = _body(4)
    L = _lengths(J)
    target, weight = _one_target(J, J[0, 0, WR])
    target[0, 2, 1, 0] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        clean_reach(J, L, target, weight)
    weight[0, 2, 1] = 0.0  # a NaN target where the weight is 0 is ignored
    clean_reach(J, L, target, weight)
    with pytest.raises(ValueError, match="joints must be"):
        clean_reach(J[..., :2], L, target, weight)
    with pytest.raises(ValueError, match="need target"):
        clean_reach(J, L, target[:, :, 0], weight)
    with pytest.raises(ValueError, match="in \\[0, 1\\]"):
        clean_reach(J, L, np.zeros_like(target), weight * 2.0)
    with pytest.raises(ValueError, match="fixed"):
        clean_reach(J, L, np.zeros_like(target), weight, fixed=9)
    with pytest.raises(ValueError, match="ramp_in"):
        ReachCleanupConfig(ramp_in=0.0)


def test_controller_schedule_ramps_to_the_grasp_and_fades_out_across_episodes():
    goal = np.array([1.0, 0.5, 1.0])
    phases = [Phase("reach", ("reach",), frames=12, hand_goal=goal, hand="left_wrist", step=0),
              Phase("act", ("stand",), frames=40, step=1)]
    L, k, fps = 16, 2, 10.0
    ctrl = Controller(phases, ["reach", "stand", "walk"], L, k, fps)
    prev = np.zeros((k, 3), np.float32)
    w, t = [], []
    for _ in range(3):
        c = ctrl.next(np.zeros(2), prev)
        assert np.all(c.reach_weight[:k] == 0) and np.all(c.reach_weight[:, 1] == 0)  # the left hand only
        w.append(c.reach_weight[k:, 0])
        t.append(c.reach_target[k:, 0])
    w, t = np.concatenate(w), np.concatenate(t)
    assert w[11] == pytest.approx(1.0)  # the grasp: the hand phase's last frame
    assert np.all(np.diff(w[:12]) >= 0) and np.all(np.diff(w[11:]) <= 0)
    assert w[0] == 0.0 and np.all(w[11 + int(0.6 * fps) + 1:] == 0)  # faded out after ramp_out
    assert 0 < w[14] < 1  # the fade crosses the episode seam (frame 14 is the next episode's first)
    assert np.abs(np.diff(w)).max() < 0.3
    np.testing.assert_allclose(t[w > 0], np.broadcast_to(goal, t[w > 0].shape))


def test_moving_part_follows_the_handle_path():
    path = np.stack([np.linspace(0, 1, 5), np.zeros(5), np.ones(5)], 1)
    phase = Phase("reach", ("open_door",), frames=10, hand_goal=path[-1], step=0,
                  info={"part": 1, "hand_path": path})
    w, t = reach_schedule(phase, np.arange(10), 10.0)
    np.testing.assert_array_equal(w, 1.0)
    np.testing.assert_allclose(t[-1], path[-1])
    assert np.all(np.diff(t[:, 0]) >= 0) and t[0, 0] < 0.05  # eased away from the grasp point


def test_no_reach_cleanup_flag():
    p = argparse.ArgumentParser()
    add_postprocess_arguments(p)
    assert postprocess_kwargs(p.parse_args([]))["cleanup"].reach.enabled is True
    assert postprocess_kwargs(p.parse_args(["--no-reach-cleanup"]))["cleanup"].reach.enabled is False


@pytest.mark.parametrize("goal, reached", [([1.05, 0.6, 1.1], True), ([1.4, 0.6, 1.0], False)])
def test_rollout_reaches_the_hand_goal_or_stretches_toward_it(goal, reached):
    from trumans.sample.plan import plan_from_dict
    from trumans.sample.rollout import sample_plan
    from trumans.sample.cleanup.pipeline import CleanupConfig
    from trumans.sample.sampler import EpisodeSampler, SamplerConfig
    from trumans.scenes.occupancy import OccupancyGrid
    from trumans.scenes.scene import Scene
    from trumans.scenes.scene_grids import SceneGrids
    from trumans.scenes.walkability import walkable_map

    grid = np.zeros((120, 120, 120), dtype=bool)
    grid[:, :, :5] = True  # floor
    occ = OccupancyGrid(grid, np.array([0.01, 0.01, -0.09]), 0.02)
    scene, wm, ck = Scene("open"), walkable_map(occ), tiny_checkpoint()
    goal = np.array(goal)
    plan = plan_from_dict({"start": [0.6, 0.6], "steps": [{"do": "reach", "target": goal.tolist(), "hand": "right"}]})
    # the untrained body stands (without overlap: an untrained network following a lead drifts off)
    unguided = dict(action_scale=1.0, goal_guidance=0.0, goal_iters=1, overlap=0)
    runs = [sample_plan(ck, EpisodeSampler(ck, SceneGrids(occ), SamplerConfig(
        steps=2, cleanup=CleanupConfig().switched(reach=on), **unguided)), scene, wm, plan, seed=0) for on in (False, True)]
    off, on = runs
    i = next(i for i, p in enumerate(on.phases) if p.hand_goal is not None)
    frames = np.flatnonzero(on.phase[0] == i)
    grasp = frames[-1]  # the hand phase's last frame: weight 1
    J = on.joints[0].astype(np.float64)
    L = bone_lengths_of(J[0])
    np.testing.assert_allclose(bone_lengths_of(J), np.broadcast_to(L, J.shape[:2]), atol=1e-4)
    s, w = J[grasp, SH], J[grasp, WR]
    assert (np.linalg.norm(w - goal) < 1e-3) == reached  # the untrained body stands still: 0.45 / 0.8 m away
    if not reached:  # out of reach after the lean: a straight arm toward the goal
        assert np.linalg.norm(w - s) == pytest.approx(L[EL] + L[WR], abs=3e-3)
        line = (goal - s) / np.linalg.norm(goal - s)
        assert np.linalg.norm((w - s) - ((w - s) @ line) * line) < 1e-3
    before = frames[0]  # the weights are 0 before the hand phase: the same motion bit for bit
    np.testing.assert_array_equal(on.joints[0, :before], off.joints[0, :before])
    d_on = np.linalg.norm(on.joints[0, frames, WR] - goal, axis=-1).min()
    d_off = np.linalg.norm(off.joints[0, frames, WR] - goal, axis=-1).min()
    assert d_on < d_off
