"""trumans.refine.post_steps: the HOI filter's post-steps as one ordered pipeline, one config, and
the command-line switches generated from its table."""
import argparse
import json
from dataclasses import fields, replace

import numpy as np
import pytest

from trumans.refine import frames_from_sequence
from trumans.refine.body_drift import DriftConfig, remove_body_drift
from trumans.refine.bones import input_bone_lengths, project_bone_lengths
from trumans.refine.floor import floor_offset, keep_above_floor
from trumans.refine.foot_lock import LockConfig, lock_feet
from trumans.refine.gate import gate_joints, noise_level
from trumans.refine.object_hinge import HingeConfig, fit_hinge
from trumans.refine.object_rest import RestConfig, pool_rest
from trumans.refine.post_args import add_post_step_arguments, post_steps_config
from trumans.refine.post_steps import STEPS, PostStepsConfig, RefinedClip, run_post_steps
from trumans.refine.residual import keep_low_frequencies
from trumans.refine.smoother_blend import blend_with_smoother

from helpers import carried_box_clip

FPS = 30.0


def _clip(category: str = "box", T: int = 90) -> RefinedClip:
    """A carried box standing in for the filter's output: the tracked input is the clip with noise
    and a gap; the 'filtered' frames the clip with a slow whole-body drift."""
    frames, _ = frames_from_sequence(carried_box_clip(T=T, seed=1), "box_0")
    frames = frames.astype(np.float64)
    rng = np.random.default_rng(0)
    tracked = frames + rng.normal(0, 0.01, frames.shape)
    tracked[30:40] = np.nan
    filtered = frames.copy()
    filtered[:, 0:72:3] += np.linspace(0, 0.05, T)[:, None]  # x of every joint
    return RefinedClip(filtered, tracked, FPS, category)


def _parse(argv: list[str]) -> PostStepsConfig:
    p = argparse.ArgumentParser()
    add_post_step_arguments(p)
    return post_steps_config(p.parse_args(argv))


def test_the_documented_order_and_reported_names():
    import trumans.refine.post_steps as mod

    names = [s.name for s in STEPS]
    assert names == ["residual", "body_drift", "foot_lock", "rest_pooling", "hinge", "gate", "smoother", "bones", "floor"] == [
        f.name for f in fields(PostStepsConfig)]
    doc = mod.__doc__
    assert [doc.index(f"``{n}``") for n in names] == sorted(doc.index(f"``{n}``") for n in names)
    d = PostStepsConfig()
    no_hinge = [n for n in names if n != "hinge"]
    assert d.runs("door") == names and d.runs("cup") == no_hinge
    assert d.steps_for("door") == ["residual", "body_drift", "foot_lock", "rest_pooling", "hand_link", "hinge", "gate",
                                   "smoother", "bones", "floor"]
    assert replace(d, hinge=replace(d.hinge, any_category=True)).runs("cup") == names
    assert replace(d, hinge=replace(d.hinge, categories=("cup",))).runs("door") == no_hinge
    assert d.switched(rest_pooling=False).runs("door") == ["residual", "body_drift", "foot_lock", "gate", "smoother", "bones", "floor"]  # the hinge needs pooled rests


def test_run_applies_the_steps_in_order_with_their_configs():
    clip = _clip("door")
    cfg = PostStepsConfig()
    body = lambda f: np.asarray(f, np.float64)[:, :72].reshape(len(f), 24, 3)
    tracked = body(clip.tracked)
    want = np.array(clip.frames, np.float32)
    want[:, :72] = keep_low_frequencies(body(clip.frames), tracked, FPS, cfg.residual).reshape(len(want), -1)
    want = remove_body_drift(want, FPS, cfg.body_drift)
    want = lock_feet(want, FPS, cfg.foot_lock)
    want = pool_rest(want, clip.tracked, FPS, cfg.rest_pooling)
    want = fit_hinge(want, clip.tracked, cfg.hinge)
    J = gate_joints(body(want), tracked, FPS, cfg.gate)
    J = blend_with_smoother(J.astype(np.float32), tracked, FPS, cfg.smoother)  # (the gate's output as stored)
    J = project_bone_lengths(J, input_bone_lengths(tracked, noise_level(tracked), cfg.bones))
    J = keep_above_floor(J, FPS, floor_offset(tracked, cfg.floor), cfg.floor)
    want = want.astype(np.float32)
    want[:, :72] = J.reshape(len(J), -1)
    np.testing.assert_allclose(run_post_steps(clip, cfg), want, atol=1e-6)  # the steps round to float32 in between


@pytest.mark.parametrize("name", [s.name for s in STEPS])
def test_a_disabled_step_changes_nothing(name):
    """Off, a step is the identity: the run equals the run of the other steps alone."""
    clip = _clip("door")
    off = PostStepsConfig().switched(**{name: False})
    frames = clip.frames
    for step in STEPS:
        if step.name in off.runs("door"):
            frames = step.apply(replace(clip, frames=frames), getattr(off, step.name))
    np.testing.assert_array_equal(run_post_steps(clip, off), frames)
    everything_off = PostStepsConfig().switched(**{s.name: False for s in STEPS})
    assert run_post_steps(clip, everything_off) is clip.frames


def test_a_parameter_reaches_its_step():
    clip = _clip()
    only_drift = PostStepsConfig().switched(residual=False, foot_lock=False, rest_pooling=False, hinge=False, gate=False,
                                            smoother=False, bones=False, floor=False)
    only_drift = replace(only_drift, body_drift=replace(only_drift.body_drift, min_rms_m=0.0))  # any drift it fits
    slow = replace(only_drift, body_drift=replace(only_drift.body_drift, speed_m_s=1.0))  # the clip walks: only a fast threshold finds stances
    np.testing.assert_array_equal(run_post_steps(clip, slow), remove_body_drift(clip.frames, FPS, slow.body_drift))
    assert not np.array_equal(run_post_steps(clip, slow), run_post_steps(clip, only_drift))
    # the hinge's turn threshold: above any turn, the hinge step leaves the object as it is
    door = _clip("door")
    only_hinge = PostStepsConfig().switched(residual=False, foot_lock=False, gate=False, smoother=False, bones=False,
                                            floor=False)
    stiff = replace(only_hinge, hinge=replace(only_hinge.hinge, min_turn_deg=180.0))
    no_hinge = only_hinge.switched(hinge=False)
    np.testing.assert_array_equal(run_post_steps(door, stiff), run_post_steps(door, no_hinge))
    assert not np.array_equal(run_post_steps(door, only_hinge), run_post_steps(door, no_hinge))


def test_config_round_trip_and_unknown_keys_refused():
    c = PostStepsConfig()
    c = replace(c, body_drift=replace(c.body_drift, speed_m_s=0.25, robust_iters=2),
                foot_lock=replace(c.foot_lock, enabled=False, stance=replace(c.foot_lock.stance, knot_s=0.7)),
                rest_pooling=replace(c.rest_pooling, hand_link=False),
                hinge=replace(c.hinge, categories=("door", "drawer")))
    d = json.loads(json.dumps(c.to_dict()))
    assert PostStepsConfig.from_dict(d) == c
    assert PostStepsConfig.from_dict({}) == PostStepsConfig()
    for bad, msg in [({"foot": {}}, r"post: unknown key\(s\) \['foot'\]"),
                     ({"hinge": {"min_turn": 5}}, r"post\.hinge: unknown key"),
                     ({"body_drift": {"speed_m_s": "fast"}}, r"post\.body_drift\.speed_m_s must be a finite number"),
                     ({"rest_pooling": {"hand_link": 1}}, r"post\.rest_pooling\.hand_link must be true or false"),
                     ({"hinge": {"ridge": 0.0}}, "hinge ridge must be a positive number"),
                     ({"foot_lock": {"stance": {"enabled": False}}}, "stance detection only")]:
        with pytest.raises(ValueError, match=msg):
            PostStepsConfig.from_dict(bad)
    with pytest.raises(ValueError, match="unknown post-steps"):
        PostStepsConfig().switched(foot=False)
    with pytest.raises(ValueError, match=r"frames and tracked must both be \(T, 235\)"):
        RefinedClip(np.zeros((5, 235)), np.zeros((4, 235)), FPS, "box")


def test_generated_switches_map_onto_the_config():
    d = PostStepsConfig()
    assert _parse([]) == d
    for flag, name in [("--no-residual", "residual"), ("--no-drift-correction", "body_drift"), ("--no-foot-lock", "foot_lock"),
                       ("--no-rest-pooling", "rest_pooling"), ("--no-hinge", "hinge"), ("--no-gate", "gate"),
                       ("--no-input-bones", "bones"), ("--no-floor", "floor")]:
        assert _parse([flag]) == d.switched(**{name: False}), flag
    assert _parse(["--no-hand-link"]) == replace(d, rest_pooling=replace(d.rest_pooling, hand_link=False))
    assert _parse(["--hinge"]) == replace(d, hinge=replace(d.hinge, any_category=True))
    assert "hinge" in _parse(["--hinge"]).runs("cup") and "hinge" not in _parse(["--no-hinge"]).runs("door")
    with pytest.raises(SystemExit):
        _parse(["--hinge", "--no-hinge"])
    got = _parse(["--set", "post.body_drift.speed_m_s=0.25", "--set", 'post.hinge.categories=["door", "drawer"]',
                  "--set", "post.foot_lock.stance.knot_s=1", "--no-foot-lock"])
    assert got.body_drift == DriftConfig(speed_m_s=0.25) and got.hinge == HingeConfig(categories=("door", "drawer"))
    assert got.foot_lock == LockConfig(enabled=False, stance=DriftConfig(knot_s=1.0))
    assert got.rest_pooling == RestConfig()
    assert _parse(["--no-hand-link", "--set", "post.rest_pooling.hand_link=true"]) == d  # --set comes last
    for bad, msg in [("cleanup.foot.blend=4", "PATH under post"), ("post.hinge", "PATH=VALUE"),
                     ("post.hinge.ridge=small", "VALUE must be JSON"), ("post.hinge.nope=1", "unknown key"),
                     ("post.hinge.enabled.x=1", "is a value, not a section")]:
        with pytest.raises(ValueError, match=msg):
            _parse(["--set", bad])
