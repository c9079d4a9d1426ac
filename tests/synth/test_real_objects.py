"""trumans.synth.real_objects: objects where hands pick up and put down, on hand-made trajectories and real clips."""
import numpy as np
import pytest

from trumans.actions import intervals_from_labels
from trumans.mocap_corpus import load_corpus
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import REST_JOINTS
from trumans.synth.hands.core import PALM_GAP, inv_h, palm_points
from trumans.synth.real_objects import (GRIP_SHARE, SUPPORT_MIN_M, fit_handled_objects, find_reaches,
                                        handled_footprints, holding_frames)

T, PICK, PUT = 150, 30, 110


def _dip(t, t0, z_hi, z_lo, half=20):
    """Palm height: z_hi, down to z_lo at t0 (cosine over ``half`` frames each side), back to z_hi."""
    u = np.clip(np.abs(t - t0) / half, 0, 1)
    return z_lo + (z_hi - z_lo) * 0.5 * (1 - np.cos(np.pi * u))


def trajectory(low=0.20, both=False, spread_at=None):
    """(T, 24, 3) joints: the body stands, walks 1 m along +x on frames 50-90, stands; the right palm
    (both palms with ``both``) reaches down to ``low`` at PICK and at PUT, held at 0.95 m between;
    with ``spread_at`` the palms open 0.3 m wider there instead of the second reach."""
    t = np.arange(T, dtype=np.float64)
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    walk = np.clip((t - 50) / 40, 0, 1)
    j[..., 0] += walk[:, None]
    z = np.where(t < 70, _dip(t, PICK, 0.95, low), 0.95)
    if spread_at is None:
        z = np.where(t >= 70, _dip(t, PUT, 0.95, low), z)
    z = np.where((t < 10) | (t > 130), 0.85, z)
    palms = {"right": np.stack([0.35 + walk, np.full(T, -0.2), z], -1),
             "left": np.stack([0.30 + walk, np.full(T, 0.2), np.full(T, 0.85)], -1)}
    if both:
        palms["left"] = palms["right"] + np.array([0.0, 0.4, 0.0])
        if spread_at is not None:
            palms["left"][:, 1] += 0.3 * np.clip((t - spread_at) / 5, 0, 1)
    for side, p in palms.items():
        j[:, J[f"{side}_wrist"]] = p + [0, 0, 0.04]
        j[:, J[f"{side}_index1"]] = p - [0, 0, 0.04]
    return j


def wrist_rotations():
    """(T, 2, 3, 3): identity, the right wrist turning 0.6 rad about z while walking."""
    R = np.repeat(np.eye(3)[None, None], T, 0).repeat(2, 1)
    a = 0.6 * np.clip((np.arange(T) - 50) / 40, 0, 1)
    R[:, 1, 0, 0], R[:, 1, 0, 1], R[:, 1, 1, 0], R[:, 1, 1, 1] = np.cos(a), -np.sin(a), np.sin(a), np.cos(a)
    return R


def test_one_hand_pick_carry_put_on_the_floor():
    j, R = trajectory(), wrist_rotations()
    reaches = find_reaches(j)
    assert [(r.frame, r.hands) for r in reaches] == [(PICK, (1,)), (PUT, (1,))]
    h = fit_handled_objects(j, R, "walk, pick up object, set down object")
    (obj,) = h.objects
    track = h.tracks[obj.name]
    assert obj.category == "bottle" and obj.dynamic and h.supports == [] and track.shape == (T, 4, 4)
    pick, put = reaches
    assert [(iv.name, iv.start, iv.end) for iv in h.intervals] == [
        ("pick_up", pick.start, pick.end), ("carry", pick.end, put.start), ("put_down", put.start, put.end)]
    # static and upright on the floor before the pick-up, the grasp point PALM_GAP from the palm
    np.testing.assert_allclose(track[:PICK], np.broadcast_to(track[0], (PICK, 4, 4)))
    np.testing.assert_allclose(obj.pose, track[0])
    assert track[0, 2, 3] == 0.0 and track[0, 2, 2] == pytest.approx(1.0)
    grasp = track[PICK] @ np.r_[obj.meta["grasp_point"], 1.0]
    palm = palm_points(j)[PICK, 1]
    assert np.linalg.norm(palm[:2] - grasp[:2]) == pytest.approx(PALM_GAP)
    assert (grasp[0] - palm[0]) > 0  # on the far side of the palm from the body (which stands at x ~ 0)
    # rigid with the right hand while carried (which turns 0.6 rad), static after the put-down
    H = holding_frames(j, R, (1,))
    rel = inv_h(H[PICK:PUT]) @ track[PICK:PUT]
    np.testing.assert_allclose(rel, np.broadcast_to(rel[0], rel.shape), atol=1e-9)
    turn = np.arctan2(track[PUT - 1, 1, 0], track[PUT - 1, 0, 0]) - np.arctan2(track[0, 1, 0], track[0, 0, 0])
    assert np.angle(np.exp(1j * turn)) == pytest.approx(0.6)
    np.testing.assert_allclose(track[PUT:], np.broadcast_to(track[PUT], (T - PUT, 4, 4)))
    assert track[PUT, 2, 3] == 0.0 and track[PUT, 2, 2] == pytest.approx(1.0)
    held = H[PUT] @ rel[0]
    assert h.release_jump_m == [pytest.approx(held[2, 3])]  # set down from the hand's height onto the floor
    assert held[2, 3] < SUPPORT_MIN_M
    assert track[PUT, 0, 3] == pytest.approx(held[0, 3]) and track[PUT, 0, 3] > 1.0  # put down where it was carried
    np.testing.assert_array_equal(h.grasp[:, 1], (np.arange(T) >= PICK) & (np.arange(T) < PUT))
    assert not h.grasp[:, 0].any()


def test_high_pick_gets_a_support_under_the_object():
    h = fit_handled_objects(trajectory(low=0.45), wrist_rotations(), "pick up")
    (obj,) = h.objects
    track = h.tracks[obj.name]
    first, second = h.supports  # under the pick-up and the put-down place
    top = 0.45 - obj.meta["grasp_point"][2]
    assert track[0, 2, 3] == pytest.approx(top) and first.meta["surface_height"] == pytest.approx(top)
    assert obj.meta["support"] == first.name and first.category == "table"
    assert first.world_mesh().bounds[1, 2] == pytest.approx(top)
    assert first.world_mesh().bounds[0, 2] == pytest.approx(0.0)
    for sup, frame in ((first, 0), (second, T - 1)):  # the object stands inside the support's top
        c = track[frame, :2, 3]
        lo, hi = sup.world_mesh().bounds[:, :2]
        assert np.all(c > lo) and np.all(c < hi)
        assert track[frame, 2, 3] == pytest.approx(sup.meta["surface_height"])
        assert not sup.world_mesh().contains(trajectory(low=0.45).reshape(-1, 3)).any()


def test_two_hands_carry_a_box_and_put_it_down_by_opening():
    j = trajectory(low=0.30, both=True, spread_at=100)
    h = fit_handled_objects(j, wrist_rotations(), "Walk and pick up box", fps=30.0)
    (obj,) = h.objects
    track = h.tracks[obj.name]
    assert obj.category == "box"
    depth, width, height = obj.meta["size"]
    assert width == pytest.approx(0.4 - 2 * PALM_GAP) and height == pytest.approx(0.45)
    assert track[0, 2, 3] == 0.0  # 0.30 - GRIP_SHARE * 0.45 < SUPPORT_MIN_M: on the floor
    # the palms hold its sides
    local = (palm_points(j)[PICK] - track[PICK, :3, 3]) @ track[PICK, :3, :3]
    np.testing.assert_allclose(np.sort(np.abs(local[:, 1])), [width / 2 + PALM_GAP] * 2)
    H = holding_frames(j, np.zeros((T, 2, 3, 3)), (0, 1))
    release = 102  # the first frame the palms are > 0.1 m farther apart (0.3 * 2 / 5 = 0.12 m)
    rel = inv_h(H[PICK:release]) @ track[PICK:release]
    np.testing.assert_allclose(rel, np.broadcast_to(rel[0], rel.shape), atol=1e-9)
    names = [iv.name for iv in h.intervals]
    assert names == ["pick_up", "carry", "put_down"] and h.intervals[2].start < release < h.intervals[2].end
    (sup,) = h.supports  # set down at hand height: on a fitted support
    assert track[-1, 2, 3] == pytest.approx(0.95 - 0.30)  # held 0.30 m above its bottom since the pick-up
    assert sup.meta["surface_height"] == pytest.approx(track[-1, 2, 3])
    assert h.grasp[PICK:release].all() and not h.grasp[release:].any() and not h.grasp[:PICK].any()
    quads = handled_footprints(h)
    assert len(quads) > 3 and all(q.shape == (4, 2) for q in quads)


def test_no_hint_no_objects_and_bad_input():
    j, R = trajectory(), wrist_rotations()
    h = fit_handled_objects(j, R, "walk in a circle")
    assert h.objects == [] and h.intervals == [] and h.grasp.shape == (T, 2) and not h.grasp.any()
    with pytest.raises(ValueError, match="wrist_rot"):
        fit_handled_objects(j, R[:, :1], "pick up")
    with pytest.raises(ValueError, match="joints"):
        fit_handled_objects(j[:, :20], R, "pick up")


def test_real_pick_clip_becomes_a_take_with_an_object_track():
    from trumans.synth.real_takes import real_sequence

    clip = next(c for c in load_corpus(split="train") if c.name == "69_70")
    seq, terms = real_sequence(clip, 0)
    pl = terms["placement"]
    track = seq.objects["fit_bottle_0"].pose
    assert seq.objects["fit_bottle_0"].category == "bottle" and "fit_bottle_0" in pl.fitted
    np.testing.assert_allclose(pl.scene.objects["fit_bottle_0"].pose, track[0], atol=1e-5)
    moved = np.linalg.norm(track[-1, :2, 3] - track[0, :2, 3])
    assert moved > 0.5  # "pick up object, set down in another place"
    assert track[0, 2, 3] >= 0 and track[-1, 2, 3] == pytest.approx(0.0, abs=1e-6)
    names = {iv.name for iv in intervals_from_labels(seq.actions, seq.action_names)}
    assert {"pick_up", "carry", "put_down"} <= names
    assert seq.extra["grasp"].any() and seq.extra["grasp"].shape == (seq.num_frames, 2)
    # the palm holds the bottle on the carried frames (within a hand's size)
    g = seq.extra["grasp"].any(axis=1)
    palms = palm_points(seq.joints[g])
    d = np.linalg.norm(palms - track[g][:, None, :3, 3], axis=-1).min(axis=1)
    assert d.max() < 0.25
    assert terms["penetration"].max() < 0.08


def test_put_down_by_the_other_hand_takes_it_over_where_the_palms_meet():
    t = np.arange(T, dtype=np.float64)
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    right = np.stack([np.full(T, 0.35), np.full(T, -0.2), np.where(t < 70, _dip(t, PICK, 0.95, 0.2), 0.95)], -1)
    meet = np.clip(1 - np.abs(t - 70) / 10, 0, 1)  # the left palm comes to the right one at frame 70
    left = np.stack([np.full(T, 0.35), 0.2 - 0.36 * meet, np.where(t >= 80, _dip(t, PUT, 0.95, 0.2), 0.95)], -1)
    for side, p in (("right", right), ("left", left)):
        j[:, J[f"{side}_wrist"]] = p + [0, 0, 0.04]
        j[:, J[f"{side}_index1"]] = p - [0, 0, 0.04]
    R = wrist_rotations()
    h = fit_handled_objects(j, R, "pick up object, set down object")
    assert [(r.frame, r.hands) for r in h.reaches] == [(PICK, (1,)), (PUT, (0,))]
    track = h.tracks[h.objects[0].name]
    for hands, a, b in (((1,), PICK, 70), ((0,), 70, PUT)):
        H = holding_frames(j, R, hands)
        rel = inv_h(H[a:b]) @ track[a:b]
        np.testing.assert_allclose(rel, np.broadcast_to(rel[0], rel.shape), atol=1e-9)
        assert h.grasp[a:b, hands[0]].all() and not h.grasp[a:b, 1 - hands[0]].any()
    assert track[-1, 2, 3] == 0.0 and abs(track[-1, 1, 3] - track[0, 1, 3]) > 0.1  # put down by the left hand


def test_removing_a_blocking_piece_removes_its_parts_and_what_stands_on_them():
    import trimesh

    from trumans.scenes.scene import Scene, SceneObject
    from trumans.synth.real_place import remove_objects

    box = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    objs = [SceneObject("cabinet_0", "cabinet", box),
            SceneObject("cabinet_0_drawer_0", "drawer", box, meta={"parent": "cabinet_0"}),
            SceneObject("cup_0", "cup", box, meta={"support": "cabinet_0_drawer_0"}),
            SceneObject("book_0", "book", box, meta={"support": "cabinet_0"}), SceneObject("table_0", "table", box)]
    scene = Scene(name="s", objects={o.name: o for o in objs})
    assert remove_objects(scene, ["cabinet_0"]) == ["book_0", "cabinet_0", "cabinet_0_drawer_0", "cup_0"]
    assert list(scene.objects) == ["table_0"]


def test_a_carry_under_way_from_the_first_frame():
    t = np.arange(T, dtype=np.float64)
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    j[..., 0] += t[:, None] / 60  # walking 0.5 m/s along +x
    sway = 0.02 * np.sin(t / 5)
    for side, y in (("left", 0.19), ("right", -0.19)):
        p = np.stack([0.35 + t / 60, np.full(T, y), 1.05 + sway], -1)
        j[:, J[f"{side}_wrist"]] = p + [0, 0, 0.04]
        j[:, J[f"{side}_index1"]] = p - [0, 0, 0.04]
    R = wrist_rotations()
    h = fit_handled_objects(j, R, "Walk and carry")
    (obj,) = h.objects
    track = h.tracks[obj.name]
    assert obj.category == "box" and h.supports == [] and h.grasp.all()
    assert [(iv.name, iv.start, iv.end) for iv in h.intervals] == [("carry", 0, T)]
    H = holding_frames(j, R, (0, 1))
    rel = inv_h(H) @ track
    np.testing.assert_allclose(rel, np.broadcast_to(rel[0], rel.shape), atol=1e-9)
    assert track[0, 2, 3] == pytest.approx(1.05 + sway[0] - GRIP_SHARE * obj.meta["size"][2])
    assert fit_handled_objects(j, R, "walk").objects == []  # only where the description carries
    j[:, J["left_wrist"], 2] -= 0.3  # one hand hanging: no box
    j[:, J["left_index1"], 2] -= 0.3
    assert fit_handled_objects(j, R, "Walk and carry").objects == []



def test_a_box_carried_from_the_first_frame_is_as_wide_as_the_carry_grip():
    """The palms hold 25 cm apart on the first 5 frames, then settle 35 cm apart for the rest of the
    carry (CMU 111_36: 25 cm on frame 0, 31-38 cm for 11 s). The box is sized by the carry's grip
    (median palm distance), not by frame 0's: before, a 22-cm box left both palms 5-7 cm off it."""
    t = np.arange(T, dtype=np.float64)
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    j[..., 0] += t[:, None] / 60
    half = np.where(t < 5, 0.125, 0.175)
    for side, sign in (("left", 1), ("right", -1)):
        p = np.stack([0.35 + t / 60, sign * half, np.full(T, 1.05)], -1)
        j[:, J[f"{side}_wrist"]] = p + [0, 0, 0.04]
        j[:, J[f"{side}_index1"]] = p - [0, 0, 0.04]
    h = fit_handled_objects(j, wrist_rotations(), "Walk and carry")
    (obj,) = h.objects
    assert obj.meta["size"][1] == pytest.approx(0.35 - 2 * PALM_GAP)
    assert h.grasp.all()
    palms = palm_points(j)
    centre = h.tracks[obj.name][:, :3, 3]
    np.testing.assert_allclose(centre[:, 1], palms[:, :, 1].mean(1), atol=1e-9)  # between the palms


def _pick_then_widen(drop_after: bool) -> np.ndarray:
    """(T, 24, 3): both palms (0.4 m apart) reach down to 0.3 m at PICK and carry the box at 1.05 m
    from frame 60; at frame 80 they open 0.15 m wider (over 5 frames) and hold so; with
    ``drop_after`` the hands then fall to hanging height (0.80 m) over frames 90-95."""
    t = np.arange(T, dtype=np.float64)
    j = np.repeat(REST_JOINTS[None].astype(np.float64), T, 0)
    z = np.where(t < 60, _dip(t, PICK, 1.05, 0.30, half=30), 1.05)
    if drop_after:
        z = z - 0.25 * np.clip((t - 90) / 5, 0, 1)
    wider = 0.15 * np.clip((t - 80) / 5, 0, 1)
    for side, y, sign in (("left", 0.2, 1), ("right", -0.2, -1)):
        p = np.stack([np.full(T, 0.35), y + sign * wider / 2, z], -1)
        j[:, J[f"{side}_wrist"]] = p + [0, 0, 0.04]
        j[:, J[f"{side}_index1"]] = p - [0, 0, 0.04]
    return j


def test_a_wider_grip_held_at_carry_height_is_not_a_release():
    """Palms that open 0.15 m after a two-hand pick-up and then hold steadily apart at carry height
    have taken a new grip (CMU 111_36, "walk and carry"): the box is carried to the end. The same
    opening followed by the hands falling to hanging height is a release there (the control)."""
    R = wrist_rotations()
    kept = fit_handled_objects(_pick_then_widen(False), R, "pick up box and carry", fps=30.0)
    (obj,) = kept.objects
    assert [iv.name for iv in kept.intervals] == ["pick_up", "carry"] and kept.intervals[1].end == T
    assert kept.grasp[PICK:].all()
    let_go = fit_handled_objects(_pick_then_widen(True), R, "pick up box and carry", fps=30.0)
    assert [iv.name for iv in let_go.intervals] == ["pick_up", "carry", "put_down"]
    release = int(np.flatnonzero(let_go.grasp.any(1))[-1]) + 1
    assert 80 < release < 86 and not let_go.grasp[release:].any()
