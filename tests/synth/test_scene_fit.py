"""trumans.scene_fit: seats under seated pelvises, beds under raised lying bodies (synthetic and real clips)."""
import numpy as np
import pytest

from trumans.mocap_corpus import load_corpus
from trumans.motion_labels import MOTION_STATES, label_states
from trumans.scene_fit import SEAT_BELOW_HIP_M, fit_beds, fit_seats
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import REST_JOINTS

SIT = MOTION_STATES.index("sit")


def seated_body(seconds=3.0, seat=0.47, yaw=0.0, at=(1.0, 2.0)):
    """Rest pose folded onto a seat of height ``seat``: thighs horizontal (towards +x turned by yaw),
    shins vertical, hips ``SEAT_BELOW_HIP_M`` above the seat."""
    j = REST_JOINTS.copy()
    thigh = j[J["left_hip"], 2] - j[J["left_knee"], 2]
    drop = j[J["left_hip"], 2] - (seat + SEAT_BELOW_HIP_M)
    legs = [J[f"{s}_{n}"] for s in ("left", "right") for n in ("knee", "ankle", "foot")]
    upper = [k for k in range(24) if k not in legs]
    j[upper, 2] -= drop
    j[legs, 0] += thigh
    for s in ("left", "right"):
        j[J[f"{s}_knee"], 2] = j[J[f"{s}_hip"], 2]  # ankles and feet keep their rest height
    c, s_ = np.cos(yaw), np.sin(yaw)
    j[:, :2] = j[:, :2] @ np.array([[c, s_], [-s_, c]]) + at
    return np.repeat(j[None], int(seconds * 30), 0)


@pytest.mark.parametrize("seat,yaw", [(0.45, 0.0), (0.70, 1.2), (0.30, -2.5)])
def test_seat_under_the_seated_pelvis(seat, yaw):
    j = seated_body(seat=seat, yaw=yaw)
    states = label_states(j, 30.0)
    assert (states == SIT).mean() > 0.9
    (obj,) = fit_seats(j, states)
    assert obj.category == "seat" and obj.meta["seat_height"] == pytest.approx(seat, abs=1e-6)
    mesh = obj.world_mesh()
    assert mesh.bounds[0, 2] == pytest.approx(0.0) and mesh.bounds[1, 2] == pytest.approx(seat)
    # the pelvis and both hips are right above the seat top, the knees beyond its front half
    probe = j[0, [J["pelvis"], J["left_hip"], J["right_hip"]]].copy()
    probe[:, 2] = seat - 0.01
    assert mesh.contains(probe).all()
    knee = j[0, [J["left_knee"]]].copy()
    knee[:, 2] = seat - 0.01
    assert not mesh.contains(knee).any()  # the seat ends before the knees (0.75 of the thigh)
    # the seat faces where the thighs point
    assert np.cos(np.arctan2(obj.pose[1, 0], obj.pose[0, 0]) - yaw) > 0.999


def test_no_seat_when_standing_or_on_the_floor():
    stand = np.repeat(REST_JOINTS[None], 90, 0)
    assert fit_seats(stand, label_states(stand, 30.0)) == []
    floor = seated_body(seat=0.08)  # hips 18 cm up: sitting on the floor
    assert fit_seats(floor, np.full(len(floor), SIT)) == []


def test_bed_under_a_raised_lying_body_not_the_floor():
    lying = np.repeat(REST_JOINTS[None], 60, 0)
    lying = lying[..., [2, 1, 0]].copy()  # head along +x, body height now along x
    lying[..., 2] = 0.55 + 0.1 * (lying[..., 2] - lying[..., 2].min())
    states = np.full(len(lying), MOTION_STATES.index("lie"))
    (bed,) = fit_beds(lying, states)
    top = bed.world_mesh().bounds[1, 2]
    body_low = lying[0, [J["pelvis"], J["spine1"], J["head"]], 2].min()
    assert body_low - 0.1 < top < body_low
    xs = lying[0, :, 0]
    lo, hi = bed.world_mesh().bounds[:, 0]
    assert lo < xs.min() and hi > xs.max()  # the whole body lies on it
    lying[..., 2] -= 0.5  # the same body on the floor: no bed
    assert fit_beds(lying, states) == []


def test_seats_for_real_seated_clips():
    """Every seated run of the real held-out clips gets a seat at a plausible height with the
    pelvis above its footprint (CMU chairs and stools are 0.3-0.8 m)."""
    n = 0
    for clip in load_corpus(split="test"):
        for seat in fit_seats(clip.joints, clip.states):
            s, e = seat.meta["frames"]
            assert 0.2 < seat.meta["seat_height"] < 0.85, (clip.name, seat.meta["seat_height"])
            mesh = seat.world_mesh()
            pel = np.median(clip.joints[s:e, J["pelvis"]], axis=0).astype(np.float64)
            pel[2] = seat.meta["seat_height"] - 0.01
            assert mesh.contains(pel[None])[0], clip.name
            n += 1
    assert n >= 5


def test_contacts_with_the_fitted_scene():
    from trumans.contacts.rule import FLOOR_NAME
    from trumans.scene_fit import fitted_contacts

    j = seated_body(seat=0.47)
    scene, contact, objects = fitted_contacts(j, label_states(j, 30.0))
    assert list(scene.objects) == ["seat_0"]
    objects = np.array(objects)
    for joint in ("left_hip", "right_hip"):  # the thighs rest on the seat
        assert contact[:, J[joint]].all() and (objects[:, J[joint]] == "seat_0").all()
    assert contact[:, J["left_foot"]].all() and (objects[:, J["left_foot"]] == FLOOR_NAME).all()
    assert not contact[:, J["head"]].any()


def test_fitted_legs_are_disjoint_bodies_and_avoid_the_body():
    """Legs share no vertex with the top (else the inside test of trumans.scenes.distance sees one open
    body and calls points beside a leg inside); a leg on a joint's path is left out."""
    from trumans.scenes.distance import SceneDistance
    from trumans.scene_fit import LEG_CLEAR_M, SEAT_LEG_M, box_object

    seat = box_object("s", "seat", 1.0, 2.0, 0.3, 0.4, 0.38, 0.45, {}, legs=True)
    assert seat.meta["legs"] == 4
    mesh = seat.world_mesh()
    rng = np.random.default_rng(0)
    local = rng.uniform([-0.3, -0.3, 0.0], [0.3, 0.3, 0.5], (400, 3))
    pts = local @ seat.pose[:3, :3].T + seat.pose[:3, 3]
    np.testing.assert_array_equal(SceneDistance({"s": mesh}).query(pts).inside, mesh.contains(pts))
    corner = seat.pose @ np.array([0.2 - SEAT_LEG_M / 2, 0.19 - SEAT_LEG_M / 2, 0.1, 1.0])  # in the (+x, +y) leg
    three = box_object("s", "seat", 1.0, 2.0, 0.3, 0.4, 0.38, 0.45, {}, legs=True, avoid=corner[None, :3])
    assert three.meta["legs"] == 3 and not three.world_mesh().contains(corner[None, :3]).any()
    away = corner[:3] + seat.pose[:3, 0] * (LEG_CLEAR_M + SEAT_LEG_M)
    assert box_object("s", "seat", 1.0, 2.0, 0.3, 0.4, 0.38, 0.45, {}, legs=True, avoid=away[None]).meta["legs"] == 4


def test_seat_sat_on_again_lower_keeps_the_lowest_and_a_seat_on_the_floor_body_is_dropped():
    from trumans.scene_fit import fit_scene

    hi, lo = seated_body(seat=0.47), seated_body(seat=0.40)
    stand = np.repeat(REST_JOINTS[None] + np.array([1.0, 2.0, 0.0]), 60, 0)
    j = np.concatenate([hi, stand, lo])
    states = label_states(j, 30.0)
    (seat,) = fit_scene(j, states).objects.values()
    assert seat.meta["seat_height"] == pytest.approx(0.40, abs=1e-6) and len(seat.meta["runs"]) == 2
    # the same seat, then the body on the floor where it stands (0.2 s after getting up): no seat
    floor = seated_body(seat=0.08, seconds=1.0)
    j = np.concatenate([hi, floor])
    states = np.r_[label_states(hi, 30.0), np.full(len(floor), MOTION_STATES.index("stand"))]
    assert fit_scene(j, states).objects == {}


def test_seat_front_cut_back_for_a_foot_on_its_edge():
    j = seated_body(seat=0.45)
    knee = j[0, J["left_knee"]]
    foot = j[:, J["left_ankle"]]
    foot[45:] = [knee[0] - 0.08, knee[1], 0.44]  # the foot pulled up onto the seat's front edge
    (seat,) = fit_seats(j, np.full(len(j), SIT))
    assert not seat.world_mesh().contains(j[:, J["left_ankle"]]).any()
    probe = j[0, [J["pelvis"]]].copy()
    probe[:, 2] = 0.44
    assert seat.world_mesh().contains(probe).all()  # still under the pelvis
