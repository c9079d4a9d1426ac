"""trumans.motion_labels, trumans.mocap_corpus and trumans.eval.realism: states, the shipped corpus, statistics."""
import json

import numpy as np
import pytest

from trumans.mocap_corpus import (CORPUS_PATH, HELD_OUT_SUBJECTS, convert_clip, decode_joints,
                                  drop_tpose_frame, encode_joints, load_corpus, write_corpus)
from trumans.motion_labels import MOTION_STATES, label_states, segments
from trumans.eval.realism import (STATISTICS, RealismClip, bootstrap_range, clip_events, clip_statistics, compare,
                                  reference_ranges, score, seams_from_goals)
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import REST_JOINTS

from helpers import TEST_DATA, seated, sit_stand_take

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


def test_transition_labels_cover_the_whole_posture_change():
    """A stand -> sit -> stand take with 0.8-s cosine transitions: ``sit_down`` and ``stand_up`` hold
    the whole hip drop and rise (each label starts with the hips within 10 % of the change from where
    they were and ends within 10 % of where they go), ``sit`` only the settled frames."""
    take, (n, drop_start) = sit_stand_take(FPS), (int(0.8 * FPS), 45)
    st = label_states(take, FPS)
    hips = 0.5 * (take[:, J["left_hip"], 2] + take[:, J["right_hip"], 2])
    top, low = hips[0], hips[drop_start + n + 10]
    for name, frm, to in (("sit_down", top, low), ("stand_up", low, top)):
        runs = segments(st == MOTION_STATES.index(name))
        assert len(runs) == 1, (name, runs)
        s, e = runs[0]
        assert abs(hips[s] - frm) < 0.1 * abs(top - low) and abs(hips[e - 1] - to) < 0.1 * abs(top - low), (name, s, e)
    sitting = np.flatnonzero(st == MOTION_STATES.index("sit"))
    assert np.abs(hips[sitting] - low).max() < 0.05 * (top - low)


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
    rep = compare([walker(cadence=100)], [walker(cadence=c) for c in (95, 100, 105)], min_events=3)
    assert set(rep["statistics"]) == set(STATISTICS)
    assert rep["statistics"]["cadence"]["inside"] is True
    assert rep["statistics"]["seated_trunk_tilt"]["inside"] is None
    out = compare([walker(cadence=140)], [walker(cadence=c) for c in (95, 100, 105)], min_events=3)
    assert out["statistics"]["cadence"]["inside"] is False
    assert 0 <= out["fraction_inside"] < rep["fraction_inside"]
    assert out["inside_count"] == round(out["fraction_inside"] * out["compared"])
    json.dumps(rep)
    # too few real events: no range, reported as such, counted neither way
    few = compare([walker(cadence=140)], [walker(cadence=c) for c in (95, 100, 105)])
    row = few["statistics"]["cadence"]
    assert row["inside"] is None and row["reference"]["lo"] is None
    assert row["reference"]["note"].startswith("n/a: 3 events in 3 clips")
    assert few["compared"] == 0


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
    """The shipped corpus (issue 35 point 3): >= 4 h, held-out subjects only in the test split, and the
    clip list data/mocap/cmu_clips.csv says why every library clip is in or out."""
    import csv
    clips = load_corpus()
    rows = list(csv.DictReader(open(CORPUS_PATH.parent / "cmu_clips.csv", newline="")))
    kept = [r for r in rows if r["split"] != "excluded"]
    assert [c.name for c in clips] == [r["clip"] for r in kept]  # the list and the npz agree, in order
    assert [c.split for c in clips] == [r["split"] for r in kept]
    assert all(r["reason"] for r in rows) and len(rows) > 2500  # every library clip has a decision
    assert {c.split for c in clips} == {"train", "test"}
    test = [c for c in clips if c.split == "test"]
    assert {c.subject for c in test} == set(HELD_OUT_SUBJECTS)
    assert not {c.subject for c in clips if c.split == "train"} & set(HELD_OUT_SUBJECTS)
    minutes = sum(len(c.joints) for c in clips) / FPS / 60
    assert minutes >= 240
    assert len({c.joints[:40].tobytes() for c in clips}) == len(clips)  # no clip twice
    states = np.concatenate([c.states for c in test])
    for s, seconds in (("walk", 300), ("sit", 100), ("stand", 200), ("lie", 20), ("sit_down", 8), ("stand_up", 8)):
        assert (states == MOTION_STATES.index(s)).sum() > seconds * FPS, s
    assert CORPUS_PATH.stat().st_size < 40e6
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
    assert main(["eval", "realism", str(tmp_path / "ds"), "--reference", str(tmp_path / "ds"), "--min-events", "3",
                 "--json"]) == 0
    rep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert rep["clips"] == 3 and rep["reference_clips"] == 3
    assert rep["statistics"]["cadence"]["value"] == pytest.approx(110, rel=0.06)
    assert rep["statistics"]["cadence"]["inside"] is True  # the median walker is inside its own set's p10-p90
    assert rep["statistics"]["seam_jerk_peak_ratio"]["note"].startswith("not measured")
    with pytest.raises(FileNotFoundError, match="not a dataset folder"):
        main(["eval", "realism", str(tmp_path / "none"), "--reference", str(tmp_path / "ds")])


# ------------------------------------------------------------------------------------ issue 35's statistics

def sit_down(descent=1.2, shove=0.0, wrist_offset=0.0, stand_s=2.0, seat_s=4.0):
    """The rest body standing ``stand_s`` s, then lowered onto a 0.5 m seat (``seated``'s pose) along
    a smoothstep over ``descent`` s while its pelvis moves backward (against its facing) by
    ``shove`` m along a sine-squared bump (peak speed 2 shove / descent), then seated ``seat_s`` s.
    ``wrist_offset``: the left wrist held this much (m) higher than the right throughout."""
    up, down = REST_JOINTS.astype(np.float64), seated(1.0)[0].astype(np.float64)
    n_stand, n_desc, n_seat = int(stand_s * FPS), int(round(descent * FPS)), int(seat_s * FPS)
    u = np.linspace(0, 1, n_desc + 1)
    s = 3 * u ** 2 - 2 * u ** 3  # smoothstep 0 -> 1
    frames = np.concatenate([np.repeat(up[None], n_stand, 0), up[None] + s[:, None, None] * (down - up)[None],
                             np.repeat(down[None], n_seat, 0)])
    heading = 0.0  # the rest pose faces +x (body_features' heading of REST_JOINTS)
    from trumans.motion_labels import body_features
    heading = float(body_features(up[None].repeat(2, 0), FPS)["heading"][0])
    back = -np.array([np.cos(heading), np.sin(heading)])
    disp = np.zeros(len(frames))
    disp[n_stand:n_stand + n_desc + 1] = shove * (u - np.sin(2 * np.pi * u) / (2 * np.pi))  # speed ~ sin^2
    disp[n_stand + n_desc + 1:] = shove
    frames[:, :, :2] += disp[:, None, None] * back
    frames[:, J["left_wrist"], 2] += wrist_offset
    return frames


def test_sit_down_descent_shove_and_symmetry():
    ev = clip_events(sit_down(descent=1.2, shove=0.3))
    assert len(ev["sitdown_backward_shove"]) == 1
    # the event runs from the last frame at >= 95 % of standing height to 2 cm above the seat, a fixed
    # share of the smoothstep: its 10 -> 90 % time is under the whole curve's (0.608 of it) and scales with it
    d12 = ev["sitdown_descent_10_90"][0]
    assert 0.3 * 1.2 < d12 < 0.608 * 1.2 + 1 / FPS
    assert clip_events(sit_down(descent=2.4, shove=0.3))["sitdown_descent_10_90"][0] == pytest.approx(2 * d12, abs=2 / FPS)
    assert ev["sitdown_backward_shove"][0] == pytest.approx(2 * 0.3 / 1.2, rel=0.05)  # peak of a sin^2 bump
    assert clip_events(sit_down(shove=0.0))["sitdown_backward_shove"][0] == pytest.approx(0.0, abs=1e-6)
    forward = clip_events(sit_down(shove=-0.3))["sitdown_backward_shove"][0]  # moving forward is no shove
    assert forward == pytest.approx(0.0, abs=1e-6)
    assert clip_events(sit_down())["sitdown_wrist_height_asymmetry"][0] == pytest.approx(0.0, abs=1e-9)
    assert clip_events(sit_down(wrist_offset=0.07))["sitdown_wrist_height_asymmetry"][0] == pytest.approx(0.07, abs=1e-6)


def test_stand_up_pause_to_walk():
    """Seated, risen back to standing (the sit-down reversed), then still for ``pause`` s, then walking:
    the statistic grows by exactly the pause."""
    got = {}
    for pause in (0.0, 1.0):
        rise = sit_down(descent=1.0, stand_s=0.0, seat_s=3.0)[::-1]
        still = np.repeat(rise[-1:], int(pause * FPS), 0)
        walk = walker(4.0)
        walk = walk - walk[:1, J["pelvis"]] * np.array([1, 1, 0]) + rise[-1:, J["pelvis"]] * np.array([1, 1, 0])
        ev = clip_events(np.concatenate([rise, still, walk]))
        assert len(ev["standup_pause_to_walk"]) == 1
        got[pause] = ev["standup_pause_to_walk"][0]
    # the end of the rise (95 % of standing height) comes before the body is fully up, and walking is
    # labelled where the 0.5 s mean ground speed passes 0.35 m/s, a few frames after it starts
    assert 0.0 < got[0.0] < 0.8
    assert got[1.0] - got[0.0] == pytest.approx(1.0, abs=2 / FPS)


def test_foot_skate_and_feet_off():
    stand = np.repeat(REST_JOINTS[None].astype(np.float64), 90, 0)
    ev = clip_events(stand)
    assert ev["stand_foot_skate_share"] == [0.0] and ev["both_feet_off_share"] == [0.0]
    slide = stand.copy()
    slide[:, :, 0] += 0.2 * np.arange(90)[:, None] / FPS  # the whole body glides at 0.2 m/s: every contact slides
    assert clip_events(slide)["stand_foot_skate_share"] == [pytest.approx(1.0)]
    hop = stand.copy()
    hop[::3] += [0, 0, 0.2]  # every third frame both feet 20 cm up
    assert clip_events(hop)["both_feet_off_share"][0] == pytest.approx(1 / 3, abs=0.02)


def test_jerk_at_10fps_and_seams():
    w = walker(6.0)
    ev = clip_events(RealismClip(w[::3], 10.0))  # the same walk given at 10 fps
    assert ev["walk_jerk_p95"] == []  # no 30 fps jerk from interpolated frames
    ref = clip_events(w)["walk_jerk_p95_10fps"][0]
    assert ev["walk_jerk_p95_10fps"][0] == pytest.approx(ref, rel=1e-6)
    # a 5 cm jump of the whole body every 14 frames: the seam statistic sees it at its phase
    j = walker(20.0)[::3].copy()
    for s in range(5, len(j), 14):
        j[s:] += [0.0, 0.05, 0.0]
    hitch = clip_events(RealismClip(j, 10.0, seams=(14, 5)))["seam_jerk_peak_ratio"][0]
    smooth = clip_events(RealismClip(walker(20.0)[::3], 10.0, seams=(14, 5)))["seam_jerk_peak_ratio"][0]
    assert hitch > 2 * smooth
    assert seams_from_goals(np.array([[15, 0, 0, 0], [29, 0, 0, 0], [20, 0, 0, 1], [43, 0, 0, 0]]),
                            np.array(["pelvis", "pelvis", "right_wrist", "pelvis"])) == (14, 2)
    assert seams_from_goals(np.zeros((1, 4)), np.array(["pelvis"])) is None


def test_bootstrap_is_seeded_and_covers():
    rng = np.random.default_rng(1)
    clips = [rng.normal(size=int(n)) for n in rng.integers(1, 4, 12)]
    a = bootstrap_range(clips, n_boot=200, seed=3)
    assert a == bootstrap_range(clips, n_boot=200, seed=3)
    assert a != bootstrap_range(clips, n_boot=200, seed=4)
    lo, hi, lo_ci, hi_ci = a
    assert lo_ci[0] <= lo <= lo_ci[1] and hi_ci[0] <= hi <= hi_ci[1]
    # coverage: the true 90th percentile of N(0, 1) (1.2816) falls inside the 95 % interval of most draws
    # (a percentile bootstrap of a tail quantile from ~60 events under-covers a little: >= 80 % of 40)
    hits = 0
    for t in range(40):
        r = np.random.default_rng(100 + t)
        clips = [r.normal(size=3) for _ in range(20)]
        _, _, _, (c0, c1) = bootstrap_range(clips, n_boot=200, seed=t)
        hits += c0 <= 1.2816 <= c1
    assert hits >= 32


def test_reference_ranges_per_event_and_na():
    refs = [RealismClip(sit_down(descent=d)) for d in (0.9, 1.0, 1.1, 1.2, 1.3, 1.4)]
    r = reference_ranges(refs, n_boot=50, min_events=5)["sitdown_descent_10_90"]
    assert r["events"] == 6 and r["clips"] == 6 and r["lo"] < r["median"] < r["hi"]
    na = reference_ranges(refs[:2], n_boot=50)["sitdown_descent_10_90"]
    assert na["lo"] is None and na["note"].startswith("n/a: 2 events in 2 clips")
    rep = score([RealismClip(sit_down(descent=0.5))], refs, n_boot=50, min_events=5)
    assert rep["statistics"]["sitdown_descent_10_90"]["inside"] is False  # a too-fast sit-down is outside
    assert rep["statistics"]["furniture_penetration_max_cm"]["note"].startswith("not measured")


def test_bad_input(tmp_path):
    from trumans.cli import console_main
    from trumans.sequence import Sequence, save_sequence

    with pytest.raises(ValueError, match="NaN"):
        clip_events(np.full((60, 24, 3), np.nan))
    with pytest.raises(ValueError, match="no input clips"):
        score([], [RealismClip(walker())])
    save_sequence(Sequence(joints=walker(2.0).astype(np.float32), fps=FPS), tmp_path / "plain.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    for f in ("plain.npz", "junk.npz", "none.npz"):
        assert console_main(["eval", "realism", "--generated", str(tmp_path / f)]) == 2
    assert console_main(["eval", "realism", str(tmp_path), "--generated", str(tmp_path / "plain.npz")]) == 2


def test_generated_sample_is_scored(tmp_path, capsys):
    """A sampled npz (joints at 10 fps, goals, sampler config, scene room:2) through the command."""
    from trumans.cli import main
    from trumans.sample.generate import GOAL_JOINTS_KEY, GOALS_KEY, SAMPLER_CONFIG_KEY
    from trumans.sequence import Sequence, save_sequence

    j = walker(20.0)[::3].astype(np.float32)
    j[..., :2] += [1.0, 1.0]
    frames = np.arange(15, len(j), 14)
    goals = np.c_[frames, np.zeros((len(frames), 3))]
    save_sequence(Sequence(joints=j, fps=10.0, scene="room:2", extra={
        SAMPLER_CONFIG_KEY: np.asarray("{}"), GOALS_KEY: goals, GOAL_JOINTS_KEY: np.asarray(["pelvis"] * len(frames))}),
        tmp_path / "g.npz")
    assert main(["eval", "realism", "--generated", str(tmp_path / "g.npz"), "--bootstrap", "50", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    st = rep["statistics"]
    assert st["seam_jerk_peak_ratio"]["value"] is not None and st["seam_jerk_peak_ratio"]["reference"]["lo"] is not None
    assert st["furniture_penetration_max_cm"]["value"] is not None and st["furniture_penetration_max_cm"]["inside"] is None
    assert st["walk_jerk_p95"]["note"].startswith("not measured: input below 30 fps")
    assert st["sitdown_descent_10_90"]["reference"]["note"].startswith("n/a:")  # the held-out corpus has 4
    assert rep["compared"] == sum(r["inside"] is not None for r in st.values())


def test_reference_counts_postures_only_where_the_description_speaks_of_them():
    """A squat or a crouched walk is labelled `sit` from the motion; a reference clip's seated and
    sit-down events count only when its description speaks of sitting (and lying events of lying)."""
    from trumans.eval.realism import RealismClip, described_postures

    assert described_postures("sit on high stool, stand up") == ("sit",)
    assert described_postures("Laying down and getting up") == ("lie",)
    assert described_postures("Get up from floor") == ("lie",)
    assert described_postures("walk stealthily") == () and described_postures("squats, lunges") == ()
    clip = next(c for c in load_corpus(split="train") if c.name == "13_01")
    seated = [k for k, (a, _, _) in STATISTICS.items() if a in ("seated", "sit-down", "stand-up")]
    free = clip_events(RealismClip(clip.joints, clip.fps, clip.states))
    vouched = clip_events(RealismClip(clip.joints, clip.fps, clip.states, postures=("sit",)))
    silent = clip_events(RealismClip(clip.joints, clip.fps, clip.states, postures=()))
    assert any(free[k] for k in seated) and all(vouched[k] == free[k] for k in STATISTICS)
    assert not any(silent[k] for k in seated)
    assert all(silent[k] == free[k] for k, (a, _, _) in STATISTICS.items() if a in ("walk", "upright"))
