"""`trumans sample` through the console script: step flags keep their order, files are written,
bad plans fail before sampling with one `trumans: error:` line and nothing written."""
from __future__ import annotations

import json

import numpy as np
import pytest

from trumans.sample.cli import steps_from_flags
from trumans.sample.sampler import SamplerConfig
from trumans.cli import console_main
from trumans.model.checkpoint import save_checkpoint
from trumans.sequence import load_sequence

from helpers import SAMPLE_VOCAB, tiny_checkpoint


@pytest.fixture(scope="module")
def ckpt_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("ck") / "gen.pt"
    save_checkpoint(path, tiny_checkpoint())
    return str(path)


def test_flags_keep_their_order():
    steps = steps_from_flags([("goto", "1,2"), ("sit_on", "chair_0:3"), ("stand_up", []), ("act", "drink:2.5"),
                              ("reach", "0.5,1,0.9:left"), ("reach", "cup_0")])
    assert steps == [{"do": "goto", "to": [1.0, 2.0]}, {"do": "sit_on", "object": "chair_0", "seconds": 3.0},
                     {"do": "stand_up"}, {"do": "act", "action": "drink", "seconds": 2.5},
                     {"do": "reach", "target": [0.5, 1.0, 0.9], "hand": "left"}, {"do": "reach", "target": "cup_0"}]
    with pytest.raises(ValueError, match="--goto must be 2"):
        steps_from_flags([("goto", "1")])


def test_sample_writes_files_and_figures(ckpt_path, tmp_path, capsys):
    out = tmp_path / "walk"
    rc = console_main(["sample", "--checkpoint", ckpt_path, "--scene", "room:2", "--start", "2.4,2.5",
                       "--goto", "2.4,3.4", "--act", "drink:1", "--out", str(out), "--formats", "npz,png",
                       "--steps", "2", "--json", "--no-progress"])
    assert rc == 0
    figs = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    D = SamplerConfig().overlap  # every episode but the last commits 14 - D new frames
    assert figs["episodes"] >= 1 and figs["frames"] == 2 + (14 - D) * (figs["episodes"] - 1) + 14
    for key in ("goal_err_cm", "penetration_max_cm", "floor_err_cm", "bone_length_cv", "transition_jerk_ratio",
                "seconds_per_episode", "realtime_factor"):
        assert key in figs
    seq = load_sequence(out.with_suffix(".npz"))
    assert seq.joints.shape == (figs["frames"], 24, 3) and list(seq.action_names) == SAMPLE_VOCAB
    assert (tmp_path / "walk_top.png").is_file()


@pytest.mark.parametrize("args, msg", [
    (["--sit-on", "sofa_99"], "no object 'sofa_99'"),
    (["--act", "dance"], "unknown action 'dance'"),
    (["--goto", "100,100"], "outside the scene"),  # refused before the occupancy grid is built
    (["--goto", "0.05,0.05"], "not on walkable floor"),  # inside the room, in its wall corner
    (["--goto", "1,2", "--formats", "npz,avi"], "--formats"),
    (["--plan", "missing.toml"], "does not exist"),
    (["--goto", "1,2", "--num-samples", "0"], "--num-samples"),
    (["--goto", "1,2", "--device", "tpu9"], "device"),
])
def test_bad_plans_fail_before_sampling(ckpt_path, tmp_path, capsys, args, msg):
    out = tmp_path / "x"
    rc = console_main(["sample", "--checkpoint", ckpt_path, "--scene", "room:2", "--out", str(out),
                       "--no-progress", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("trumans: error:") and msg in err[0], err
    assert not list(tmp_path.iterdir())  # nothing written


def test_missing_or_wrong_checkpoint(tmp_path, capsys):
    rc = console_main(["sample", "--checkpoint", str(tmp_path / "none.pt"), "--out", str(tmp_path / "x")])
    assert rc == 2 and "does not exist" in capsys.readouterr().err
    np.save(tmp_path / "junk.npy", np.zeros(3))
    (tmp_path / "junk.pt").write_bytes((tmp_path / "junk.npy").read_bytes())
    rc = console_main(["sample", "--checkpoint", str(tmp_path / "junk.pt"), "--out", str(tmp_path / "y")])
    assert rc == 2 and "not a readable trumans checkpoint" in capsys.readouterr().err


def test_sample_refuses_bombs_and_missing_devices_before_any_work(tmp_path, capsys):
    from trumans.cli import console_main

    cases = {"--max-seconds": ("inf", "(0.0, 86400.0]"), "--num-samples": ("1000000", "[1, 256]"),
             "--device": ("cuda:7", "cuda"), "--seed": (str(2 ** 64), "[0, 4294967295]")}
    for flag, (value, said) in cases.items():
        if flag == "--device":
            import torch
            if torch.cuda.device_count() > 7:
                continue
        assert console_main(["sample", "--out", str(tmp_path / "x"), flag, value]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and flag in err[0] and said in err[0]
    assert not any(tmp_path.iterdir())
