"""The files under examples/ are what the README and docs say they are, and the commands that use them run."""
from __future__ import annotations

import json

import numpy as np

from trumans.cli import console_main
from trumans.sample.plan import load_plan
from trumans.sequence import load_sequence

from helpers import REPO_ROOT

EXAMPLES = REPO_ROOT / "examples"


def test_tracked_example_is_a_tracked_sequence_of_its_truth():
    tracked = load_sequence(EXAMPLES / "tracked_carry.npz", allow_missing=True)
    truth = load_sequence(EXAMPLES / "tracked_carry_truth.npz")
    assert tracked.num_frames == truth.num_frames and tracked.fps == truth.fps == 30.0
    assert list(tracked.objects) == list(truth.objects) and tracked.objects["fit_box_0"].category == "box"
    missing = np.isnan(tracked.joints).any(axis=(1, 2))
    assert 0 < missing.mean() < 1  # occlusions and dropouts, as a tracker gives
    err = np.nanmean(np.linalg.norm(tracked.joints - truth.joints, axis=-1))
    assert 0.01 < err < 0.1  # centimetres of tracker error, not a different motion
    assert np.isfinite(truth.joints).all() and truth.rotations is not None


def test_refine_runs_on_the_tracked_example(tmp_path, capsys):
    out = tmp_path / "refined.npz"
    assert console_main(["refine", str(EXAMPLES / "tracked_carry.npz"), "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["object"] == "fit_box_0" and summary["category"] == "box" and summary["frames"] == 364
    refined = load_sequence(out)
    assert refined.num_frames == 364 and np.isfinite(refined.joints).all()


def test_plan_example_is_valid_in_the_default_room():
    from trumans.sample.plan import validate_plan
    from trumans.scenes.procedural import make_room
    from trumans.scenes.spec import DEFAULT_ROOM_SEED
    from trumans.model.checkpoint import load_checkpoint

    plan = load_plan(EXAMPLES / "plan_sit_drink.toml")
    assert [s.kind for s in plan.steps] == ["sit_on", "stand_up", "goto", "act"]
    validate_plan(plan, make_room(DEFAULT_ROOM_SEED), load_checkpoint(REPO_ROOT / "models" / "generator.pt",
                                                                     kind="generator").vocabulary)
