"""`trumans track --scene` takes the sample / view scene specs that have movable objects ('default', room:SEED, a
scene folder; the spec the sequence records when --scene is not given) and refuses the others with the forms
that work; `--device` reaches the contact predictor (refine, track, eval refine / contacts / train: the flag is
parsed, a missing CUDA is refused in one line before any loading, and the network lands on the device)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from trumans.cli import main
from trumans.sequence import Sequence, save_sequence
from trumans.skeleton import NUM_JOINTS, REST_JOINTS

IDENTITY_6D = np.array([1, 0, 0, 0, 1, 0], np.float32)


def _standing(path, scene: str = "", frames: int = 45, xy=(2.0, 2.0)):
    """A person standing still at ``xy`` (rest pose, identity local rotations), recording scene spec ``scene``."""
    j = REST_JOINTS.astype(np.float32)
    j[:, :2] += np.asarray(xy, np.float32) - j[0, :2]
    seq = Sequence(joints=np.repeat(j[None], frames, 0), fps=30.0,
                   rotations=np.tile(IDENTITY_6D, (frames, NUM_JOINTS, 1)), scene=scene)
    save_sequence(seq, path)
    return path


def _last_json(capsys) -> dict:
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def _refusal(capsys, argv: list, *needles: str) -> str:
    """The console script's exit status 2 with one error line holding every needle."""
    from trumans.cli import console_main

    capsys.readouterr()
    assert console_main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("trumans: error:"), err
    for n in needles:
        assert n in err, err
    return err


def test_track_runs_in_a_procedural_room_given_or_recorded(tmp_path, capsys):
    seq = _standing(tmp_path / "s.npz", scene="room:2")
    assert main(["track", str(seq), "--out", str(tmp_path / "a.npz"), "--scene", "default", "--json"]) == 0
    a = _last_json(capsys)
    assert a["frames"] == 45 and a["device"] == "cpu"
    assert main(["track", str(seq), "--out", str(tmp_path / "b.npz"), "--json"]) == 0  # the recorded room:2
    b = _last_json(capsys)
    assert b["frames"] == 45
    from trumans.sequence import load_sequence

    # the default room is room:2: the same movable objects driven either way
    assert set(load_sequence(tmp_path / "a.npz").objects) == set(load_sequence(tmp_path / "b.npz").objects) != set()


def test_track_refuses_scenes_it_cannot_use(tmp_path, capsys):
    from helpers import REPO_ROOT as ROOT

    seq = _standing(tmp_path / "s.npz")
    mesh = ROOT / "examples" / "room_mesh.obj"
    _refusal(capsys, ["track", seq, "--out", tmp_path / "o.npz", "--scene", mesh], "mesh file", "room:SEED", "default")
    _refusal(capsys, ["track", seq, "--out", tmp_path / "o.npz"], "records none", "--scene")
    _refusal(capsys, ["track", seq, "--out", tmp_path / "o.npz", "--scene", tmp_path / "nope"], "is not a folder")
    _refusal(capsys, ["track", seq, "--out", tmp_path / "o.npz", "--scene", "room:x"], "room:SEED")
    assert not (tmp_path / "o.npz").exists()


@pytest.mark.parametrize("argv", [["refine", "x.npz", "--out", "o.npz"], ["track", "x.npz", "--out", "o.npz"],
                                  ["eval", "refine"], ["eval", "contacts"], ["eval", "train", "--checkpoint", "c.pt"]])
def test_device_flag_on_every_network_command(argv, capsys):
    """--help says what runs on the device; without CUDA, --device cuda is one line naming the fix, before any
    file is read (the inputs here do not exist)."""
    with pytest.raises(SystemExit):
        main([*argv[:2 if argv[0] == "eval" else 1], "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "--device DEV" in out and "runs there" in out
    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA: the refusal cannot be shown")
    _refusal(capsys, [*argv, "--device", "cuda"], "no CUDA", "--device cpu")
    _refusal(capsys, [*argv, "--device", "tpu"], "not a device")


def test_networks_land_on_the_requested_device(monkeypatch):
    """The library calls behind the flags put the networks on the device (cpu here; cuda on a GPU machine)."""
    from trumans.refine.pipeline import HOIFilter
    from trumans.track.model_io import load_contact_models

    dev = "cuda" if torch.cuda.is_available() else "cpu"
    filt = HOIFilter.load(device=dev)
    assert {p.device.type for p in filt.model.parameters()} == {dev}
    assert filt.diffusion.alphas_cumprod.device.type == dev
    model = load_contact_models(None, device=dev)
    assert {p.device.type for p in model.parameters()} == {dev}
    from trumans.track.predictor import predict_contacts

    prob, cls = predict_contacts(model, np.tile(IDENTITY_6D, (40, NUM_JOINTS, 1)), stride=3)
    assert prob.shape == (40, 2) and isinstance(prob, np.ndarray) and np.isfinite(prob).all()


def test_commands_hand_the_device_to_the_networks(tmp_path, monkeypatch, capsys):
    """refine / track / eval train pass --device to the loaders (spied; the real loaders are tested above)."""
    import trumans.refine.pipeline as pipeline
    import trumans.track.model_io as model_io
    import trumans.train.evaluate as train_eval

    seen = {}

    class Stop(Exception):
        pass

    def spy(name):
        def f(*a, device=None, **k):
            seen[name] = device
            raise Stop
        return f

    monkeypatch.setattr(pipeline.HOIFilter, "load", classmethod(lambda cls, *a, device=None, **k: spy("refine")(device=device)))
    monkeypatch.setattr(model_io, "load_contact_models", spy("track"))
    monkeypatch.setattr(train_eval, "evaluate_checkpoint", spy("eval_train"))
    from helpers import REPO_ROOT as ROOT

    tracked = ROOT / "examples" / "tracked_carry.npz"
    seq = _standing(tmp_path / "s.npz", scene="room:2")
    for argv in (["refine", tracked, "--out", tmp_path / "r.npz"], ["track", seq, "--out", tmp_path / "t.npz"],
                 ["eval", "train", "--checkpoint", tracked]):
        with pytest.raises(Stop):
            main([str(a) for a in argv] + ["--device", "cpu"])
    assert seen == {"refine": "cpu", "track": "cpu", "eval_train": "cpu"}
