"""trumans.motion_labels, trumans.mocap_corpus and trumans.eval.realism: states, the shipped corpus, statistics."""
import json

import numpy as np
import pytest

from trumans.mocap_corpus import (CORPUS_PATH, HELD_OUT_SUBJECTS, convert_clip, decode_joints,
                                  drop_tpose_frame, encode_joints, load_corpus, write_corpus)
from trumans.motion_labels import MOTION_STATES, label_states, segments
from trumans.eval.realism import STATISTICS, clip_statistics, compare, reference_range
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import REST_JOINTS

from helpers import TEST_DATA

FPS = 30.0


def walker(seconds=6.0, speed=1.0, cadence=120.0, bob=0.02):
    """Rest pose moving along +x at ``speed`` with the legs swinging fore-aft (one step every
    60/cadence s: left and right ankles/feet/knees in antiphase) and a sinusoidal pelvis bob at the
    step rate."""
    t = np.arange(int(seconds * FPS)) / FPS
    j = np.repeat(REST_JOINTS[None], len(t), 0).copy()
    j[:, :, 0] += speed * t[:, None]
    stride = 2 * speed * 60 / cadence  # m per stride (2 steps)
    swing = 0.5 * stride / 2 * np.sin(np.pi * cadence / 60 * t)  # ankles +-(step length / 2)
    for side, sgn in (("left", 1), ("right", -1)):
        for name, w in (("knee", 0.5), ("ankle", 1.0), ("foot", 1.0)):
            j[:, J[f"{side}_{name}"], 0] += sgn * w * swing
    j[:, :, 2] += bob * np.cos(2 * np.pi * cadence / 60 * t)[:, None] * (np.arange(24) != J["left_ankle"])[None]
    return j


def seated(seconds=8.0):
    """A body sitting on a 0.45 m seat: thighs horizontal, shins vertical, trunk upright."""
    j = REST_JOINTS.copy()
    hip_z, knee_z = j[J["left_hip"], 2], j[J["left_knee"], 2]
    thigh = hip_z - knee_z
    drop = hip_z - 0.5
    up = [J[n] for n in ("pelvis", "left_hip", "right_hip", "spine1", "spine2", "spine3", "neck", "head", "left_collar",
                         "right_collar", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
                         "right_wrist", "left_index1", "right_index1")]
    j[up, 2] -= drop
    for side in ("left", "right"):
        for n in ("knee", "ankle", "foot"):
            j[J[f"{side}_{n}"], 0] += thigh
        j[J[f"{side}_knee"], 2] = j[J[f"{side}_hip"], 2]
    return np.repeat(j[None], int(seconds * FPS), 0)


# ------------------------------------------------------------------------------------ states

def test_states_of_a_walker_and_a_sitter():
    assert np.mean(label_states(walker(), FPS) == MOTION_STATES.index("walk")) > 0.9
    assert np.mean(label_states(seated(), FPS) == MOTION_STATES.index("sit")) > 0.9
    stand = np.repeat(REST_JOINTS[None], 60, 0)
    assert (label_states(stand, FPS) == MOTION_STATES.index("stand")).all()
    lying = stand.copy()
    lying[..., [0, 2]] = lying[..., [2, 0]]  # body along x, at the rest pose's height scale
    lying[..., 2] = 0.1 + 0.05 * (lying[..., 2] > lying[:, :1, 2])
    assert (label_states(lying, FPS) == MOTION_STATES.index("lie")).all()


def test_segments():
    assert segments(np.array([0, 1, 1, 0, 1], bool)) == [(1, 3), (4, 5)]
    assert segments(np.zeros(3, bool)) == []


# ------------------------------------------------------------------------------------ statistics

def test_walker_statistics_are_its_parameters():
    s = clip_statistics(walker(cadence=110, speed=1.1))
    assert s["cadence"] == pytest.approx(110, rel=0.06)
    assert s["step_length"] == pytest.approx(1.1 * 60 / 110, rel=0.06)
    assert s["pelvis_bob_regularity"] > 0.9  # a pure sinusoid repeats every step
    assert s["seated_trunk_tilt"] is None and s["sitdown_head_drop"] is None  # it never sits
    # jerk of a sinusoid: A (2 pi f)^3 for the swinging ankle
    assert 0 < s["walk_jerk_p95"] < 0.25 * (2 * np.pi * 110 / 120) ** 3 * 1.2 + 0.02 * (2 * np.pi * 110 / 60) ** 3


def test_seated_statistics():
    s = clip_statistics(seated())
    trunk = REST_JOINTS[J["neck"]] - 0.5 * (REST_JOINTS[J["left_hip"]] + REST_JOINTS[J["right_hip"]])
    rest_tilt = np.degrees(np.arccos(trunk[2] / np.linalg.norm(trunk)))  # the rest pose leans 3 deg back (hips -> neck)
    assert s["seated_trunk_tilt"] == pytest.approx(rest_tilt, abs=0.5)
    assert s["seated_pelvis_motion_5s"] == pytest.approx(0, abs=0.01)
    assert s["seated_foot_stagger"] == pytest.approx(0, abs=0.01)  # perfect symmetry


def test_compare_and_range():
    assert reference_range([1.0, 3.0]) == (1.0, 3.0)
    lo, hi = reference_range(list(np.arange(11.0)))
    assert (lo, hi) == (1.0, 9.0)
    rep = compare([walker(cadence=100)], [walker(cadence=c) for c in (95, 100, 105)])
    assert set(rep["statistics"]) == set(STATISTICS)
    assert rep["statistics"]["cadence"]["inside"] is True
    assert rep["statistics"]["seated_trunk_tilt"]["inside"] is None
    out = compare([walker(cadence=140)], [walker(cadence=c) for c in (95, 100, 105)])
    assert out["statistics"]["cadence"]["inside"] is False
    assert 0 <= out["fraction_inside"] < rep["fraction_inside"]
    json.dumps(rep)


# ------------------------------------------------------------------------------------ corpus

def test_encoding_round_trip():
    j = walker(2.0) + np.random.default_rng(0).normal(0, 0.001, (60, 24, 3))
    start, d2 = encode_joints(j)
    assert start.dtype == np.int32 and d2.dtype == np.int16 and d2.shape == (58, 24, 3)
    assert np.abs(decode_joints(start, d2) - j).max() <= 0.5e-4 + 1e-6
    jump = j.copy()
    jump[30:] += 5.0
    with pytest.raises(ValueError, match="jump"):
        encode_joints(jump)


def test_tpose_frame_is_dropped():
    t = walker(1.0)  # the rest pose is a T-pose
    seq = t.copy()
    for n in ("left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_index1", "right_index1"):
        seq[:, J[n], 2] -= 0.4  # arms down
    assert len(drop_tpose_frame(t)) == len(seq) - 1
    assert len(drop_tpose_frame(seq)) == len(seq)


def test_conversion_is_deterministic(tmp_path):
    a = convert_clip(TEST_DATA / "cmu_13_10_daz_first12keys.fbx", "13_10", "reach")
    b = convert_clip(TEST_DATA / "cmu_13_10_daz_first12keys.fbx", "13_10", "reach")
    write_corpus(tmp_path / "a.npz", [a], {"x": 1})
    write_corpus(tmp_path / "b.npz", [b], {"x": 1})
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()
    (c,) = load_corpus(tmp_path / "a.npz")
    assert c.name == "13_10" and c.subject == "13" and c.split == "train" and c.fps == 30.0
    np.testing.assert_array_equal(c.joints, a.joints)
    assert len(c.joints) == 13  # 12 keys at 24 fps less the T-pose key: 10/24 s -> 13 frames at 30 fps
    assert abs(np.percentile(c.joints[:, [J["left_foot"], J["right_foot"]], 2].min(1), 5) - REST_JOINTS[J["left_foot"], 2]) < 1e-3


def test_shipped_corpus():
    clips = load_corpus()
    assert len(clips) == 181
    assert {c.split for c in clips} == {"train", "test"}
    test = [c for c in clips if c.split == "test"]
    assert {c.subject for c in test} == set(HELD_OUT_SUBJECTS)
    minutes = sum(len(c.joints) for c in clips) / FPS / 60
    assert 50 < minutes < 62
    states = np.concatenate([c.states for c in test])
    for s, seconds in (("walk", 60), ("sit", 30), ("stand", 30), ("lie", 10), ("sit_down", 5), ("stand_up", 3)):
        assert (states == MOTION_STATES.index(s)).sum() > seconds * FPS, s
    assert CORPUS_PATH.stat().st_size < 10e6
    for c in clips[:20]:
        assert c.joints.dtype == np.float32 and c.joints.shape[1:] == (24, 3) and len(c.states) == len(c.joints)


def test_load_corpus_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="build_mocap_corpus"):
        load_corpus(tmp_path / "none.npz")
    with pytest.raises(ValueError, match="split must be"):
        load_corpus(split="val")


def test_cli_eval_realism(tmp_path, capsys):
    from trumans.cli import main
    from trumans.dataset import DatasetWriter
    from trumans.importers.cli import write_dataset
    from trumans.sequence import Sequence

    seqs = [(f"w{c}", Sequence(joints=walker(cadence=c).astype(np.float32), fps=FPS)) for c in (100, 110, 120)]
    with DatasetWriter(tmp_path / "ds", "test", {}) as writer:
        write_dataset(writer, seqs, {}, name="walkers", seed=0)
    assert main(["eval", "realism", str(tmp_path / "ds"), "--reference", str(tmp_path / "ds"), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert rep["dataset_clips"] == 3 and rep["reference_clips"] == 3
    assert rep["statistics"]["cadence"]["dataset"] == pytest.approx(110, rel=0.06)
    assert rep["fraction_inside"] == 1.0  # a dataset is inside its own range
    with pytest.raises(FileNotFoundError, match="not a dataset folder"):
        main(["eval", "realism", str(tmp_path / "none"), "--reference", str(tmp_path / "ds")])
