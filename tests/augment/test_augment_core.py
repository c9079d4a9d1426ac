"""Augmenting one sequence: analytic seat / table cases, successive and two-hand contacts, variations,
bad inputs."""
import numpy as np
import pytest
import trimesh

from trumans.augment.core import augment_sequence, find_intervals, sequence_pose, AugmentConfig
from trumans.synth.cases import make_case
from trumans.augment.variations import Variation, apply_variation, map_contact_points, normalized_coords
from trumans.scenes.scene import Scene, SceneObject
from trumans.skeleton import JOINT_INDEX as J, bone_lengths

FEET = [J["left_ankle"], J["right_ankle"], J["left_foot"], J["right_foot"]]


def _raise(scene, name, dz, key):
    h = scene.objects[name].meta[key]
    return Variation(name, "scale", scale=(1.0, 1.0, (h + dz) / h))


@pytest.fixture(scope="module")
def sit():
    return make_case("sit", 3)


def test_seat_raised_15cm_lifts_pelvis_15cm_and_feet_stay(sit):
    seq, scene = sit
    out = augment_sequence(seq, scene, [_raise(scene, "chair", 0.15, "seat_height")])
    pel = [iv for iv in out.intervals if iv.joint == 0 and iv.obj == "chair"]
    assert len(pel) == 1 and np.allclose(pel[0].offset, [0, 0, 0.15], atol=1e-4)
    s, e = pel[0].start, pel[0].end
    d = out.sequence.joints[s:e, 0] - seq.joints[s:e, 0]
    assert np.abs(d - [0, 0, 0.15]).max() < 1e-3  # analytic: the pelvis rides up with the seat
    assert np.abs(out.sequence.joints[:, FEET] - seq.joints[:, FEET]).max() < 2e-3  # planted
    assert np.abs(out.sequence.joints[:15] - seq.joints[:15]).max() < 1e-5  # far from the contact: untouched
    assert np.abs(bone_lengths(out.sequence.joints) - bone_lengths(seq.joints)).max() < 1e-5
    assert out.report["unreachable_frames"] == 0 and out.report["contact_err_cm"] < 0.1
    assert out.result.smooth.max() <= 1.0 + 1e-9
    # the saved rotations + root reproduce the saved joints
    P, _, _ = sequence_pose(out.sequence)
    assert np.abs(P - out.sequence.joints).max() < 1e-4
    assert out.scene.objects["chair"].meta["seat_height"] == pytest.approx(scene.objects["chair"].meta["seat_height"] + 0.15)


def test_two_hands_follow_a_raised_table():
    seq, scene = make_case("two_hands", 4)
    out = augment_sequence(seq, scene, [_raise(scene, "table", 0.10, "surface_height")])
    for w in (J["left_wrist"], J["right_wrist"]):
        ivs = [iv for iv in out.intervals if iv.joint == w and iv.obj == "table"]
        assert ivs, "both hands touch the table"
        s, e = ivs[0].start, ivs[0].end
        assert np.abs(out.sequence.joints[s:e, w] - seq.joints[s:e, w] - [0, 0, 0.10]).max() < 2e-3
    assert np.abs(out.sequence.joints[:, FEET] - seq.joints[:, FEET]).max() < 2e-3
    assert out.result.smooth.max() <= 1.0 + 1e-9


def test_successive_contacts_both_hold_and_targets_stay_smooth():
    seq, scene = make_case("successive", 5)
    out = augment_sequence(seq, scene, [Variation("table", "move", translation=(0.06, 0.08, 0.0), yaw=0.05)])
    ch = [iv for iv in out.intervals if iv.obj == "table"]
    assert {iv.joint for iv in ch} >= {J["left_wrist"], J["right_wrist"]}
    r = out.result
    for iv in ch:
        e = np.linalg.norm(r.joints[iv.start:iv.end, iv.joint] - r.contact_target[iv.start:iv.end, iv.joint], axis=-1)
        assert e.mean() < 0.01
    assert r.smooth.max() <= 1.0 + 1e-9
    assert np.abs(bone_lengths(r.joints) - bone_lengths(np.asarray(seq.joints, np.float64))).max() < 1e-6


def test_scale_move_and_replace_map_contact_points():
    box = SceneObject("box", "table", trimesh.creation.box((1.0, 0.6, 0.8)), pose=np.eye(4))
    box.mesh.apply_translation([0, 0, 0.4])
    p = np.array([[0.2, 0.1, 0.8], [0.5, 0.0, 0.3]])  # on the top and on the +x face
    assert np.allclose(normalized_coords(box, p), [[0.7, 2 / 3, 1.0], [1.0, 0.5, 0.375]])
    sc = apply_variation(box, Variation("box", "scale", scale=(1.0, 1.0, 1.25)))
    assert np.allclose(map_contact_points(box, sc, p), [[0.2, 0.1, 1.0], [0.5, 0.0, 0.375]], atol=1e-6)
    mv = apply_variation(box, Variation("box", "move", translation=(0.3, -0.2, 0.0)))
    assert np.allclose(map_contact_points(box, mv, p), p + [0.3, -0.2, 0.0], atol=1e-6)
    rep = trimesh.creation.cylinder(radius=0.4, height=0.7)
    rp = apply_variation(box, Variation("box", "replace", replacement="cyl"), rep)
    q = map_contact_points(box, rp, p)
    assert np.abs(rp.world_mesh().nearest.signed_distance(q)).max() < 1e-4  # on the new surface
    assert q[0, 2] == pytest.approx(0.7, abs=1e-4)  # a top contact stays on the (lower) top


def test_bad_inputs(sit):
    seq, scene = sit
    with pytest.raises(ValueError, match="unknown object"):
        augment_sequence(seq, scene, [Variation("sofa", "scale", scale=(1, 1, 1.1))])
    with pytest.raises(ValueError, match="replacement"):
        augment_sequence(seq, scene, [Variation("chair", "replace", replacement="nope")])
    with pytest.raises(ValueError, match="mesh is empty"):
        SceneObject("ghost", "chair", trimesh.Trimesh())
    far = SceneObject("lamp", "lamp", trimesh.creation.box((0.2, 0.2, 1.0)), pose=np.array(
        [[1, 0, 0, 5.0], [0, 1, 0, 5.0], [0, 0, 1, 0.5], [0, 0, 0, 1]]))
    scene2 = Scene(scene.name, static=scene.static, objects={**scene.objects, "lamp": far})
    with pytest.raises(ValueError, match="never touches"):
        augment_sequence(seq, scene2, [Variation("lamp", "scale", scale=(1, 1, 1.2))])
    with pytest.raises(ValueError, match="scale must be"):
        Variation("chair", "scale", scale=(1, -1, 1))
    with pytest.raises(ValueError, match="kind"):
        Variation("chair", "squash")
    with pytest.raises(ValueError, match="no variations"):
        augment_sequence(seq, scene, [])


def test_find_intervals_groups_seat_contacts(sit):
    seq, scene = sit
    P, G, _ = sequence_pose(seq)
    ivs, closest = find_intervals(P, G, seq, scene, AugmentConfig())
    seat = [iv for iv in ivs if iv.obj == "chair"]
    assert {iv.joint for iv in seat} >= {0}
    assert len({(iv.start, iv.end) for iv in seat}) == 1  # the torso's seat contacts fade together
    floor = [iv for iv in ivs if iv.obj == "floor_plane"]
    assert {iv.joint for iv in floor} >= {J["left_foot"], J["right_foot"]}
    assert closest.shape == P.shape


def test_rigid_hand_offsets_average_wrist_and_finger_on_shared_frames():
    from trumans.augment.core import rigid_hand_offsets
    from trumans.augment.offsets import ContactInterval
    from trumans.skeleton import JOINT_INDEX
    w, f = JOINT_INDEX["right_wrist"], JOINT_INDEX["right_index1"]
    iw = ContactInterval(w, "drawer", 2, 8)
    iw.frame_offset = np.tile([0.10, 0.0, 0.0], (6, 1))
    jf = ContactInterval(f, "drawer", 5, 10)
    jf.frame_offset = np.tile([0.0, 0.02, 0.0], (5, 1))
    other = ContactInterval(JOINT_INDEX["left_wrist"], "drawer", 0, 4)
    other.frame_offset = np.tile([0.3, 0.0, 0.0], (4, 1))
    rigid_hand_offsets([iw, jf, other], {"drawer"}, 12)
    np.testing.assert_allclose(iw.frame_offset[:3], [[0.10, 0, 0]] * 3)  # frames 2-4: wrist alone
    np.testing.assert_allclose(iw.frame_offset[3:], [[0.05, 0.01, 0]] * 3)  # frames 5-7: shared
    np.testing.assert_allclose(jf.frame_offset[:3], [[0.05, 0.01, 0]] * 3)
    np.testing.assert_allclose(jf.frame_offset[3:], [[0.0, 0.02, 0]] * 2)  # frames 8-9: finger alone
    np.testing.assert_allclose(other.frame_offset, [[0.3, 0, 0]] * 4)  # the other hand is untouched


def test_resting_legs_move_rigidly_with_the_lying_body():
    """Knees-up lying: pelvis, hips and both ankles touch the mattress, the knees do not. A
    footprint scale maps the ankles' points inwards; the resting body moves as one rigid piece,
    so the pelvis-ankle distances are kept (the legs cannot stretch)."""
    from trumans.augment.core import rigid_body_offsets
    from trumans.augment.offsets import ContactInterval
    from trumans.skeleton import JOINT_INDEX
    T = 5
    names = ["pelvis", "left_hip", "right_hip", "left_ankle", "right_ankle"]
    pts = {"pelvis": [0.0, 0.0, 0.5], "left_hip": [0.0, 0.1, 0.5], "right_hip": [0.0, -0.1, 0.5],
           "left_ankle": [0.8, 0.1, 0.5], "right_ankle": [0.8, -0.1, 0.5]}
    closest = np.zeros((T, 24, 3))
    ivs = []
    for n in names:
        j = JOINT_INDEX[n]
        closest[:, j] = pts[n]
        iv = ContactInterval(j, "bed", 0, T)
        p = np.asarray(pts[n])
        iv.frame_offset = np.tile(p * np.array([0.9, 0.9, 1.0]) - p + [0, 0, -0.1], (T, 1))  # footprint x0.9, 10 cm lower
        ivs.append(iv)
    rigid_body_offsets(ivs, closest, {"bed"}, T)
    new = {n: closest[0, JOINT_INDEX[n]] + iv.frame_offset[0] for n, iv in zip(names, ivs)}
    for a in ("left_ankle", "right_ankle"):
        d0 = np.linalg.norm(np.subtract(pts[a], pts["pelvis"]))
        assert np.linalg.norm(new[a] - new["pelvis"]) == pytest.approx(d0, abs=1e-9)
    assert all(new[n][2] == pytest.approx(0.4) for n in names)  # the body still sinks with the bed
