"""One sampler config: ``SamplerConfig()`` is what ``trumans sample`` does, it round-trips through
plain data (unknown keys refused), the command-line switches are generated from the guidance and
cleanup tables and map onto it, every guidance term follows one protocol with its weight in the
config, and the sampled npz records the config used."""
from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from trumans.cli import console_main
from trumans.model.checkpoint import save_checkpoint
from trumans.sample.cleanup.foot import FootCleanupConfig
from trumans.sample.cleanup.pipeline import STEPS, CleanupConfig
from trumans.sample.cli import SAMPLER_CONFIG_KEY
from trumans.sample.cli import add_arguments as add_sample_arguments
from trumans.sample.eval_synthesis import add_arguments as add_eval_arguments
from trumans.sample.guidance import TERMS, GuidanceConfig, GuidanceInputs, Prediction, build_terms
from trumans.sample.guidance.base import canonical_to_world
from trumans.sample.guidance.goal import GoalTerm, GoalTermConfig
from trumans.sample.guidance.penetration import PenetrationTerm, PenetrationTermConfig
from trumans.sample.guidance.seat import SeatTerm, SeatTermConfig
from trumans.sample.rollout import start_context
from trumans.sample.sampler import QUALITY_SCHEDULE, EpisodeSampler, Goal, SamplerConfig
from trumans.sample.sampling_args import add_postprocess_arguments, postprocess_kwargs, sampler_config
from trumans.scenes.sdf import SceneSDF
from trumans.sequence import load_sequence

from helpers import SAMPLE_VOCAB, box_room, tiny_checkpoint


def _parser(add) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    add(p)
    return p


def _switches() -> argparse.ArgumentParser:
    return _parser(add_postprocess_arguments)


def test_the_default_config_is_what_the_commands_do():
    c = SamplerConfig()
    assert (c.goal_guidance, c.goal_iters, c.guided_steps, c.scene_scale, c.action_scale, c.steps, c.eta, c.overlap) == \
        (45.0, 2, 4, 1.0, 2.0, 8, 0.0, 5)
    assert c.guidance.goal.heading_weight == 6.0
    q = SamplerConfig(**QUALITY_SCHEDULE)  # the earlier default, kept for comparison (benchmarks/sampling_speed.py)
    assert (q.steps, q.goal_guidance, q.goal_iters, q.guided_steps, q.guidance.goal.heading_weight) == (20, 20.0, 3, 0, 3.0)
    assert sampler_config(_parser(add_sample_arguments).parse_args(["--out", "x"])) == c
    assert sampler_config(_parser(add_eval_arguments).parse_args([])) == c
    assert c.guidance == GuidanceConfig() and c.cleanup == CleanupConfig()


def test_config_round_trips_through_json_and_refuses_unknown_keys():
    c = SamplerConfig(steps=7, action_scale=1.5, guidance=GuidanceConfig(seat=SeatTermConfig(weight=2.0)),
                      cleanup=CleanupConfig(foot=FootCleanupConfig(blend=5, scene=False)).switched(reach=False))
    d = json.loads(json.dumps(c.to_dict()))
    assert SamplerConfig.from_dict(d) == c
    assert set(d["cleanup"]) == {s.name for s in STEPS} and set(d["guidance"]) == {t.name for t in TERMS}
    assert all("enabled" in v for v in list(d["cleanup"].values()) + list(d["guidance"].values()))
    assert SamplerConfig.from_dict({"cleanup": {"seam": {"frames": 5}}}) == replace(
        SamplerConfig(), cleanup=replace(CleanupConfig(), seam=replace(CleanupConfig().seam, frames=5)))  # keys left out keep defaults
    for bad, msg in [({"stepz": 3}, r"unknown key\(s\) \['stepz'\]"),
                     ({"cleanup": {"foot": {"blnd": 3}}}, r"cleanup\.foot: unknown key"),
                     ({"cleanup": {"feet": {}}}, "unknown key"),
                     ({"cleanup": {"foot": {"enabled": 1}}}, r"cleanup\.foot\.enabled must be true or false"),
                     ({"steps": 2.5}, "steps must be a whole number"),
                     ({"guidance": {"seat": {"weight": "heavy"}}}, "must be a finite number"),
                     ({"guidance": {"seat": {"weight": -1.0}}}, "seat weight must be"),
                     ({"cleanup": "off"}, "must be a mapping")]:
        with pytest.raises(ValueError, match=msg):
            SamplerConfig.from_dict(bad)


def test_each_generated_switch_turns_off_exactly_its_entry():
    p = _switches()
    assert postprocess_kwargs(p.parse_args([])) == {"guidance": GuidanceConfig(), "cleanup": CleanupConfig()}
    for step in STEPS:
        got = postprocess_kwargs(p.parse_args([f"--no-{step.flag}"]))
        assert got == {"guidance": GuidanceConfig(), "cleanup": CleanupConfig().switched(**{step.name: False})}, step.name
    for term in TERMS:
        got = postprocess_kwargs(p.parse_args([f"--no-{term.flag}"]))
        assert got == {"guidance": GuidanceConfig().switched(**{term.name: False}), "cleanup": CleanupConfig()}, term.name


def test_todays_flag_names_still_work():
    got = postprocess_kwargs(_switches().parse_args(
        ["--no-foot-cleanup", "--no-support-lift", "--no-seat-guidance", "--no-penetration-guidance",
         "--no-scene-pushout", "--no-arm-pushout", "--no-reach-cleanup", "--seam-blend", "5"]))
    off = CleanupConfig().switched(foot=False, support_lift=False, scene_pushout=False, arm_pushout=False, reach=False)
    assert got["cleanup"] == replace(off, seam=replace(off.seam, frames=5))
    assert got["guidance"] == GuidanceConfig().switched(seat=False, penetration=False)


def test_set_reaches_any_parameter_and_refuses_bad_paths():
    got = postprocess_kwargs(_switches().parse_args(
        ["--set", "cleanup.foot.blend=4", "--set", "guidance.seat.weight=2", "--set",
         'cleanup.support_lift.seated_actions=["sit", "lie"]', "--no-foot-cleanup"]))
    assert got["cleanup"].foot == FootCleanupConfig(enabled=False, blend=4)
    assert got["guidance"].seat.weight == 2.0 and got["cleanup"].support_lift.seated_actions == ("sit", "lie")
    for bad, msg in [("steps=3", "PATH under guidance or cleanup"), ("cleanup.foot.blend", "PATH=VALUE"),
                     ("cleanup.foot.blend=four", "VALUE must be JSON"), ("cleanup.foot.nope=1", "unknown key"),
                     ("cleanup.seam.frames.x=1", "is a value, not a section"),
                     ("cleanup.foot.blend.x=1", r"config\.cleanup\.foot\.blend must be a whole number")]:
        with pytest.raises(ValueError, match=msg):
            postprocess_kwargs(_switches().parse_args(["--set", bad]))


def _inputs(config: GuidanceConfig, goals: list[Goal], sdf: SceneSDF | None) -> tuple[list, Prediction]:
    ck = tiny_checkpoint(2)
    s = EpisodeSampler(ck, None, SamplerConfig(steps=2, guidance=config))
    ctx = start_context(ck, np.array([0.9, 1.0]), 0.2, batch=len(goals))
    labels = np.zeros((len(goals), 16, len(SAMPLE_VOCAB)), np.float32)
    cond = s.condition(ctx, labels, goals)
    terms = build_terms(config, GuidanceInputs(cond, tuple(goals), s.layout, s.L, s.k, 0.12, sdf))
    x0 = torch.randn((len(goals), s.L, s.layout.dim), generator=torch.Generator().manual_seed(0)).requires_grad_(True)
    mean, std = (torch.as_tensor(v, dtype=torch.float32) for v in (s.norm.mean, s.norm.std))
    return terms, Prediction(x0, mean, std, s.k, *canonical_to_world(cond))


def test_terms_follow_the_table_and_skip_what_is_off_or_idle():
    sdf = SceneSDF(box_room())
    goals = [Goal((1.5, 1.0), heading=0.3, pelvis_z=((8, 0.5), (9, 0.5)))]
    terms, pred = _inputs(GuidanceConfig(), goals, sdf)
    assert [type(t) for t in terms] == [GoalTerm, SeatTerm, PenetrationTerm]
    total = sum(t.loss(pred) for t in terms)
    g, = torch.autograd.grad(total, pred.x0)
    assert total.ndim == 0 and torch.isfinite(g).all() and g.abs().sum() > 0
    assert [type(t) for t in _inputs(GuidanceConfig().switched(seat=False), goals, sdf)[0]] == [GoalTerm, PenetrationTerm]
    idle = [Goal((1.5, 1.0), guide=False)]  # no guided goal, no seat, no scene: nothing to build
    assert _inputs(GuidanceConfig(), idle, None)[0] == []


def test_term_weights_come_from_the_config():
    sdf = SceneSDF(box_room())
    goals = [Goal((1.5, 1.0), heading=0.3, pelvis_z=((8, 0.5), (9, 0.5)))]

    def losses(config: GuidanceConfig) -> dict:
        terms, pred = _inputs(config, goals, sdf)
        return {type(t): float(t.loss(pred).detach()) for t in terms}

    one = losses(GuidanceConfig())
    heavy = losses(GuidanceConfig(goal=GoalTermConfig(heading_weight=0.0), seat=SeatTermConfig(weight=2.0),
                                  penetration=PenetrationTermConfig(weight=3.0)))
    assert heavy[SeatTerm] == pytest.approx(4.0 * one[SeatTerm], rel=1e-5)  # squared: W and the target scale
    assert heavy[PenetrationTerm] == pytest.approx(3.0 * one[PenetrationTerm], rel=1e-5)
    assert heavy[GoalTerm] < one[GoalTerm]  # without the heading term only the position is left


def test_carried_goals_are_guided_at_their_frames():
    """GuidanceInputs.carried (the earlier episode's goals on the frames an overlap makes again): a
    carried pelvis goal pulls the hips at its frame, with its heading; a hand goal its joint there."""
    ck = tiny_checkpoint(2)
    s = EpisodeSampler(ck, None, SamplerConfig(steps=2))
    ctx = start_context(ck, np.array([0.9, 1.0]), 0.2)
    labels = np.zeros((1, 16, len(SAMPLE_VOCAB)), np.float32)
    goals = (Goal((1.5, 1.0)),)
    cond = s.condition(ctx, labels, list(goals))
    plain = GoalTerm.build(GoalTermConfig(), GuidanceInputs(cond, goals, s.layout, s.L, s.k, 0.12, None))
    carried = ((Goal((1.2, 1.1), frame=6, heading=0.5), Goal((1.3, 1.0, 1.1), joint="right_wrist", frame=5)),)
    term = GoalTerm.build(GoalTermConfig(), GuidanceInputs(cond, goals, s.layout, s.L, s.k, 0.12, None, carried))
    assert [t[1] for t in plain.targets] == [15]
    assert [t[1] for t in term.targets] == [15, 6, 6, 5]  # pelvis position + heading at 6, the wrist at 5
    x0 = torch.zeros((1, s.L, s.layout.dim), requires_grad=True)
    mean, std = (torch.as_tensor(v, dtype=torch.float32) for v in (s.norm.mean, s.norm.std))
    g, = torch.autograd.grad(term.loss(Prediction(x0, mean, std, s.k, *canonical_to_world(cond))), x0)
    moved = torch.nonzero(g[0].abs().sum(-1) > 0).flatten().tolist()
    assert moved == [5, 6, 15]
    skipped = ((Goal((1.2, 1.1), frame=6, guide=False),),)
    assert len(GoalTerm.build(GoalTermConfig(), GuidanceInputs(cond, goals, s.layout, s.L, s.k, 0.12, None,
                                                                skipped)).targets) == 1


def test_the_sampled_npz_records_the_config_used(tmp_path, capsys):
    ck = tmp_path / "gen.pt"
    save_checkpoint(ck, tiny_checkpoint())
    out = tmp_path / "walk"
    rc = console_main(["sample", "--checkpoint", str(ck), "--scene", "room:2", "--start", "2.4,2.5", "--goto", "2.4,3.0",
                       "--out", str(out), "--formats", "npz", "--steps", "2", "--json", "--no-progress",
                       "--no-arm-pushout", "--seam-blend", "4", "--set", "cleanup.foot.blend=5"])
    assert rc == 0
    figs = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert figs["written"] == [str(out.with_suffix(".npz"))]
    saved = SamplerConfig.from_dict(json.loads(str(load_sequence(out.with_suffix(".npz")).extra[SAMPLER_CONFIG_KEY])))
    cleanup = CleanupConfig(foot=FootCleanupConfig(blend=5)).switched(arm_pushout=False)
    assert saved == SamplerConfig(steps=2, cleanup=replace(cleanup, seam=replace(cleanup.seam, frames=4)))
