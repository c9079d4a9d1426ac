"""`trumans data synth`: a tiny build's invariants, determinism, resume, and the metric functions."""
from __future__ import annotations

import json

import numpy as np
import pytest

from trumans.cli import main
from trumans.dataset import Dataset
from trumans.skeleton import bone_lengths, forward_kinematics, rest_offsets
from trumans.eval import metrics
from trumans.synth.build import SynthConfig, build_dataset, split_rooms
from trumans.synth.vocab import SYNTH_ACTIONS

KEYS = ("sequences", "frames", "hours", "rooms", "action_frames", "frames_per_s", "bone_length_dev_mm",
        "foot_skate_per_step_cm", "penetration_max_cm", "grasp_dist_cm")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth")
    summary = build_dataset(SynthConfig(out=str(out), hours=0.012, rooms=3, seed=5, workers=2), progress=False)
    return out, summary


def test_summary_and_index(built):
    out, s = built
    for k in KEYS:
        assert k in s
    assert s["rooms"] == 3 and s["sequences"] >= 3
    assert s["hours"] >= 0.012 and s["frames"] == round(s["hours"] * 3600 * 30)
    assert set(s["action_frames"]) == set(SYNTH_ACTIONS)
    assert s["bone_length_dev_mm"] < 0.1
    ds = Dataset(out)
    assert ds.vocabulary == list(SYNTH_ACTIONS) and ds.fps == 30
    assert ds.hash == s["hash"] and len(ds) == s["sequences"]
    for sid in ds.scene_ids:
        assert (ds.scene_dir(sid) / "scene.json").is_file()
        assert ds.occupancy(sid).grid.any()
    seq0 = ds.load(0)
    dynamic = {n for n, o in ds.scene(seq0.scene).objects.items() if o.dynamic}
    assert dynamic and set(seq0.objects) == dynamic, "every dynamic object has a pose track"


def test_splits_are_disjoint_by_room(built):
    out, _ = built
    ds = Dataset(out)
    rooms = {sp: {ds.load(p).scene for p in ds.split(sp)} for sp in ds.split_names}
    assert all(len(v) > 0 for v in rooms.values())
    names = list(rooms)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert not rooms[a] & rooms[b]
    assert set().union(*rooms.values()) == set(ds.scene_ids)
    sp = split_rooms([f"r{i}" for i in range(50)], seed=1)
    assert [len(sp[k]) for k in ("train", "val", "test")] == [40, 5, 5]


def test_sequence_invariants(built):
    out, _ = built
    ds = Dataset(out)
    for path in ds.files:
        seq = ds.load(path)
        T = seq.num_frames
        assert seq.contacts.shape == (T, 24) and seq.contacts.dtype == bool
        assert seq.rotations.shape == (T, 24, 6)
        a = seq.actions
        assert np.all((a == 0) | ((a >= 1) & (a <= 2)))
        assert (a > 0).any(axis=1).all(), "every frame carries at least one action"
        on = a > 0
        both = on[1:] & on[:-1]
        assert np.all(np.diff(a, axis=0)[both] > 0), "progress increases within a run"
        # bone lengths exact: joints are FK of the stored rotations on the actor's offsets
        off = seq.extra["offsets"].astype(np.float64)
        bl = bone_lengths(seq.joints)
        np.testing.assert_allclose(bl, np.broadcast_to(np.linalg.norm(off[1:], axis=-1), bl.shape), atol=1e-5)
        # feet touch the floor on most frames of a synthetic take
        assert seq.contacts[:, [10, 11]].any(axis=1).mean() > 0.5
        for name, ob in seq.objects.items():
            assert ob.pose.shape == (T, 4, 4) and np.isfinite(ob.pose).all() and ob.category
        step = np.linalg.norm(np.diff(seq.joints, axis=0), axis=-1)
        assert step.max() < 0.3, "no joint teleports (> 9 m/s) between primitives"


def test_determinism_and_resume(built, tmp_path):
    out, s = built
    s2 = build_dataset(SynthConfig(out=str(tmp_path / "b"), hours=0.012, rooms=3, seed=5, workers=1), progress=False)
    assert s2["hash"] == s["hash"]
    a, b = Dataset(out), Dataset(tmp_path / "b")
    for pa, pb in zip(a.files, b.files):
        np.testing.assert_array_equal(a.load(pa).joints, b.load(pb).joints)
    # resume: every room is complete, nothing is regenerated, the CLI prints the summary last
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["data", "synth", "--out", str(out), "--hours", "0.012", "--rooms", "3", "--seed", "5", "--real-share", "0",
                     "--json"]) == 0
    last = json.loads(buf.getvalue().strip().splitlines()[-1])
    assert last["resumed_rooms"] == 3 and last["hash"] == s["hash"]
    s3 = build_dataset(SynthConfig(out=str(tmp_path / "c"), hours=0.004, rooms=1, seed=6, workers=1), progress=False)
    assert s3["hash"] != s["hash"]


def test_cli_bad_input(capsys):
    from trumans.cli import console_main

    assert console_main(["data", "synth", "--out", "/tmp/never_written", "--hours", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("trumans: error: argument --hours: -1 is out of range") and "data synth --help" in err


def test_metric_functions():
    off = rest_offsets(1.05)
    rot = np.tile(np.eye(3), (4, 24, 1, 1))
    J, _ = forward_kinematics(rot, np.tile(off[0], (4, 1)), off)
    assert metrics.bone_length_dev_mm(J, off) < 1e-6
    J2 = J.copy()
    u = (J[2, 15] - J[2, 12]) / np.linalg.norm(J[2, 15] - J[2, 12])
    J2[2, 15] += 0.003 * u  # head 3 mm further along the neck->head bone
    assert metrics.bone_length_dev_mm(J2, off) == pytest.approx(3.0, abs=1e-6)
    # two steps of one foot: planted (0 slide) and sliding 1 cm/frame over 5 contact frames (4 cm)
    foot = np.zeros((12, 1, 3))
    foot[6:11, 0, 0] = 0.01 * np.arange(5)
    foot[11, 0, 0] = 1.0  # after the run: the lift-off move is not counted
    contact = np.zeros((12, 1), bool)
    contact[0:4, 0] = True
    contact[6:11, 0] = True
    np.testing.assert_allclose(metrics.foot_slides(foot, contact), [0.0, 0.04])
    assert metrics.foot_skate_cm(foot, contact) == pytest.approx(2.0)
    signed = np.full((2, 24), 1.0)
    signed[1, 0] = 0.08  # pelvis 8 cm above the seat: its 10 cm contact radius sinks 2 cm in
    facing = np.ones((2, 24), bool)
    assert metrics.penetration_max_cm(metrics.penetration_depth(signed, facing)) == pytest.approx(2.0)
    facing[1, 0] = False  # seat not in an outward direction: 9 cm core radius, 1 cm in
    assert metrics.penetration_max_cm(metrics.penetration_depth(signed, facing)) == pytest.approx(1.0)
    signed[0, 3] = -0.01  # spine1 centre 1 cm inside a solid: contact radius 10 cm + 1 cm
    assert metrics.penetration_max_cm(metrics.penetration_depth(signed, facing)) == pytest.approx(11.0)
    assert metrics.grasp_dist_cm(np.array([0.01, 0.03])) == pytest.approx(2.0)
    with pytest.raises(ValueError, match=r"\(T, 24\)"):
        metrics.penetration_depth(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="offsets"):
        metrics.bone_length_dev_mm(J, off[:5])
