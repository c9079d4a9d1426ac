"""Real takes in `trumans data synth`: corpus train clips placed in procedural rooms that leave their path free."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.scenes.io import load_scene
from trumans.scenes.occupancy import scene_occupancy
from trumans.scenes.scene import Scene
from trumans.scenes.walkability import walkable_map
from trumans.dataset import Dataset
from trumans.mocap_corpus import HELD_OUT_SUBJECTS, load_corpus
from trumans.motion_labels import MOTION_STATES
from trumans.sequence import load_sequence
from trumans.skeleton import JOINT_INDEX
from trumans.synth.build import SynthConfig, build_dataset
from trumans.synth.real_place import BODY_RADIUS, place_clip, quad_distance, turn_and_move
from trumans.synth.real_takes import clip_labels, select_clips
from trumans.synth.vocab import SYNTH_ACTIONS


@pytest.fixture(scope="module")
def train():
    return load_corpus(split="train")


@pytest.fixture(scope="module")
def built(tmp_path_factory, train):
    out = tmp_path_factory.mktemp("real") / "ds"
    share = 3 / len(train)
    s = build_dataset(SynthConfig(out=str(out), hours=0.002, rooms=1, seed=2, workers=1, real_share=share),
                      progress=False)
    return out, s


def test_select_clips_seeded_train_only(train):
    a, b = select_clips(train, 0.1, 3), select_clips(train, 0.1, 3)
    assert [c.name for c in a] == [c.name for c in b] and len(a) == round(0.1 * len(train))
    assert [c.name for c in select_clips(train, 0.1, 4)] != [c.name for c in a]
    assert select_clips(train, 0.0, 3) == [] and len(select_clips(train, 1.0, 3)) == len(train)
    test = load_corpus(split="test")
    with pytest.raises(ValueError, match="train split"):
        select_clips(train[:2] + test[:1], 1.0, 0)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        select_clips(train, 1.5, 0)


def test_quad_distance_analytic():
    quad = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    p = np.array([[1.0, 0.5], [3.0, 0.5], [-1.0, -1.0], [1.0, 1.25]])
    np.testing.assert_allclose(quad_distance(p, quad), [0.0, 1.0, np.sqrt(2.0), 0.25])


def test_turn_and_move_is_rigid(train):
    j = train[0].joints[:20].astype(np.float64)
    k = turn_and_move(j, 0.7, np.array([1.0, -2.0]))
    np.testing.assert_allclose(np.linalg.norm(k[:, 1] - k[:, 0], axis=-1), np.linalg.norm(j[:, 1] - j[:, 0], axis=-1),
                               atol=1e-12)
    np.testing.assert_allclose(k[..., 2], j[..., 2])


def test_labels_follow_states_and_descriptions():
    states = np.array([MOTION_STATES.index(s) for s in ["stand"] * 5 + ["sit_down"] * 3 + ["sit"] * 6 + ["walk"] * 4])
    lab = clip_labels(states, "drinking a soda")
    on = lab > 0
    a = {n: i for i, n in enumerate(SYNTH_ACTIONS)}
    assert on[:5, a["stand"]].all() and not on[5:, a["stand"]].any()
    assert on[8:14, a["sit"]].all() and on[14:, a["walk"]].all()
    assert on[:5, a["drink"]].all() and on[8:14, a["drink"]].all() and not on[5:8, a["drink"]].any()
    np.testing.assert_allclose(lab[8:14, a["sit"]], 1 + np.linspace(0, 1, 6), atol=1e-6)  # progress 0 -> 1
    assert not on[:, a["carry"]].any()


def test_placement_keeps_path_free_and_seats_under_pelvis(train):
    clip = next(c for c in train if c.name == "13_01")  # sit on a high stool, stand up
    assert (clip.states == MOTION_STATES.index("sit")).sum() > 60
    pl = place_clip(clip.joints, clip.states, 5, clip.name)
    assert pl is not None and pl.fitted
    # rigid: the placed clip is the recorded one turned and moved
    j0 = clip.joints.astype(np.float64)
    np.testing.assert_allclose(pl.joints, turn_and_move(j0, pl.yaw, pl.shift), atol=1e-4)
    W, D = pl.scene.meta["size"]
    pel = pl.joints[:, JOINT_INDEX["pelvis"], :2]
    assert pel.min() >= BODY_RADIUS - 1e-6 and (pel <= np.array([W, D]) - BODY_RADIUS + 1e-6).all()
    seat = pl.scene.objects[pl.fitted[0]]
    s, e = seat.meta["frames"]
    quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * seat.meta["size"][:2] / 2 @ seat.pose[:2, :2].T
    assert (quad_distance(pel[s:e].astype(np.float64), quad + seat.pose[:2, 3]) == 0).all()


def _without(scene: Scene, names: list[str]) -> Scene:
    return Scene(scene.name, dict(scene.static), {n: o for n, o in scene.objects.items() if n not in names}, {})


def test_built_real_takes(built, tmp_path):
    out, s = built
    ds = Dataset(out)
    import json

    index = json.loads((out / "index.json").read_text())
    real = index["real"]
    assert s["real"]["clips"] == 3 and s["real"]["takes"] + s["real"]["skipped"] == 3 and len(real) == s["real"]["takes"] >= 2
    test_names = {c.name for c in load_corpus(split="test")}
    train_names = {c.name: c for c in load_corpus(split="train")}
    for rel, src in real.items():
        name = src.removeprefix("cmu:")
        assert name in train_names and name not in test_names and name.split("_")[0] not in HELD_OUT_SUBJECTS
        assert out / rel in ds.files
        seq = load_sequence(out / rel)
        assert str(seq.extra["source"]) == src and seq.action_names == list(SYNTH_ACTIONS)
        assert seq.contacts.shape == (seq.num_frames, 24) and seq.rotations.shape == (seq.num_frames, 24, 6)
        # the recorded motion moved rigidly (heights kept), through the rotation fit (a few mm)
        clip = train_names[name]
        np.testing.assert_allclose(seq.joints[..., 2], clip.joints[..., 2], atol=0.01)
        # the walked path is free: walkable in the room without the furniture fitted to the clip
        scene = load_scene(out / index["scenes"][seq.scene])
        free = _without(scene, scene.meta["fitted"])
        wm = walkable_map(scene_occupancy(free, tmp_path / seq.scene), body_radius=BODY_RADIUS - 0.04)
        pel = seq.joints[:, JOINT_INDEX["pelvis"], :2]
        assert wm.query(pel).all(), f"{rel}: pelvis off the walkable floor"
        # feet on the floor somewhere in every take (contacts computed against the room)
        assert seq.contacts[:, [JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"]]].any()


def test_real_share_zero_adds_nothing(tmp_path):
    s = build_dataset(SynthConfig(out=str(tmp_path / "a"), hours=0.002, rooms=1, seed=2, workers=1), progress=False)
    assert "real" not in s
    with pytest.raises(ValueError, match="real_share"):
        SynthConfig(out="x", real_share=1.5)


def test_fit_scene_one_seat_per_place_and_none_in_the_way(train):
    from trumans.scene_fit import fit_scene, fit_seats, in_the_way

    clip = next(c for c in train if c.name == "14_28")  # sits twice on the same high stool
    assert len(fit_seats(clip.joints, clip.states)) == 2
    (seat,) = fit_scene(clip.joints, clip.states).objects.values()
    assert len(seat.meta["runs"]) == 2
    # a joint inside the seat for >= 0.5 s far from any seated run: the seat is in the way
    T = 400
    sit = MOTION_STATES.index("sit")
    joints = np.repeat(clip.joints[seat.meta["frames"][0]][None], T, 0).astype(np.float64)
    states = np.full(T, MOTION_STATES.index("stand"))
    seat.meta["frames"], states[:60] = [0, 60], sit
    top = seat.meta["seat_height"]
    joints[300:300 + 15, JOINT_INDEX["left_wrist"]] = seat.pose[:3, 3] + [0.0, 0.0, top - 0.02]
    assert in_the_way(seat, joints, states)
    assert not in_the_way(seat, joints[:310], states[:310])  # only 10 frames inside
    states[290:330] = sit  # seated again there: the wrist resting on the seat is no conflict
    assert not in_the_way(seat, joints, states)


def test_realism_source_filter(built, capsys):
    import json

    from trumans.cli import console_main
    from trumans.eval.realism_cli import load_clips

    out, s = built
    index = json.loads((out / "index.json").read_text())
    real = load_clips(str(out), source="real")
    proc = load_clips(str(out), source="procedural")
    assert len(real) == len(index["real"]) and len(real) + len(proc) == s["sequences"] and len(proc) >= 1
    assert sorted(len(j) for j in real) == sorted(
        len(load_sequence(out / r).joints) for r in index["real"])
    assert console_main(["eval", "realism", "corpus:train", "--source", "real"]) == 2
    assert "drop --source" in capsys.readouterr().err


def _resting_hand(frames: int, ahead: float, height: float = 0.80) -> np.ndarray:
    from trumans.motion_labels import body_features
    from trumans.skeleton import REST_JOINTS

    j = np.repeat(REST_JOINTS[None].astype(np.float64), frames, 0)
    h = body_features(j, 30.0)["heading"][0]
    fwd = np.array([np.cos(h), np.sin(h)])
    w, i = JOINT_INDEX["right_wrist"], JOINT_INDEX["right_index1"]
    j[:, w, :2] = j[:, JOINT_INDEX["pelvis"], :2] + ahead * fwd
    j[:, w, 2] = height
    j[:, i] = j[:, w] + np.array([*(0.08 * fwd), 0.0])
    return j


def test_table_under_a_resting_hand():
    from trumans.scene_fit import WRIST_ABOVE_TOP_M, fit_scene, fit_tables

    j = _resting_hand(60, 0.4)
    states = np.zeros(len(j), np.int64)
    (table,) = fit_tables(j, states)
    assert table.category == "table"
    assert table.meta["surface_height"] == pytest.approx(0.80 - WRIST_ABOVE_TOP_M, abs=1e-9)
    mesh = table.world_mesh()
    under = j[0, JOINT_INDEX["right_wrist"]] - [0.0, 0.0, WRIST_ABOVE_TOP_M + 0.01]
    assert mesh.contains(under[None]).all() and not mesh.contains(j[0]).any()
    assert mesh.bounds[1, 2] == pytest.approx(0.80 - WRIST_ABOVE_TOP_M)
    assert list(fit_scene(j, states).objects) == ["table_0"]
    assert fit_tables(j[:20], states[:20]) == []  # rests for less than 1 s
    assert fit_tables(_resting_hand(60, 0.1), states) == []  # a hand at the side: no table
    assert fit_tables(_resting_hand(60, 0.4, height=0.45), states) == []  # lower than a table
