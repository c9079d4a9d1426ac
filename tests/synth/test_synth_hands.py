"""Hand-interaction primitives: contact at grasp frames, rigid carrying, door / drawer limits,
desk work, push / pull, bone lengths, smoothness, labels, bad inputs."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from trumans.scenes.scene import SceneObject
from trumans.skeleton import JOINT_INDEX, bone_lengths, rest_offsets
from trumans.contacts.rule import JOINT_RADIUS
from trumans.synth import hands, locomotion, posture
from trumans.synth.hands.clearance import ARM_JOINTS
from trumans.synth.legs import standing_state
from trumans.synth.motion import Motion, concat_motions
from trumans.synth.vocab import SYNTH_ACTIONS

OFF = rest_offsets(1.0)
UPPER = [JOINT_INDEX[n] for n in ("spine3", "neck", "head", "left_shoulder", "right_shoulder", "left_elbow",
                                  "right_elbow", "left_wrist", "right_wrist", "left_index1", "right_index1")]


def pose_xyz_yaw(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    p = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    p[:2, :2] = [[c, -s], [s, c]]
    p[:3, 3] = [x, y, z]
    return p


def bottle() -> SceneObject:
    r, h = 0.035, 0.22
    mesh = trimesh.creation.cylinder(radius=r, height=h, sections=32)
    mesh.apply_translation([0, 0, h / 2])
    meta = {"size": [2 * r, 2 * r, h], "grasp_point": [r, 0.0, 0.55 * h], "grasp_axis": [-1.0, 0.0, 0.0]}
    return SceneObject("bottle_0", "bottle", mesh, dof="free", dynamic=True, meta=meta)


def phone() -> SceneObject:
    mesh = trimesh.creation.box(extents=[0.075, 0.15, 0.008])
    mesh.apply_translation([0, 0, 0.004])
    meta = {"size": [0.075, 0.15, 0.008], "grasp_point": [0.0, 0.0, 0.008], "grasp_axis": [0.0, 0.0, -1.0]}
    return SceneObject("phone_0", "phone", mesh, dof="free", dynamic=True, meta=meta)


def door() -> SceneObject:
    w, hgt, th = 0.85, 2.0, 0.04
    leaf = trimesh.creation.box(bounds=[[-th / 2, -w / 2, 0], [th / 2, w / 2, hgt]])
    yh = -(w / 2 - 0.08)
    lever = trimesh.creation.box(bounds=[[th / 2, yh - 0.06, 0.988], [th / 2 + 0.06, yh + 0.06, 1.012]])
    # Opens into the person's side (+x), as trumans.scenes.furniture.door: hinge on the +x face at +y.
    meta = {"handle": [th / 2 + 0.045, yh, 1.0], "max_angle": 1.4, "open_sign": 1.0, "width": w}
    return SceneObject("door_0", "door", trimesh.util.concatenate([leaf, lever]), dof="hinge",
                       hinge_point=np.array([th / 2, w / 2, 0.0]), axis=np.array([0.0, 0.0, 1.0]),
                       dynamic=True, meta=meta)


def drawer() -> SceneObject:
    mesh = trimesh.creation.box(bounds=[[-0.22, -0.3, 0.0], [0.22, 0.3, 0.2]])
    meta = {"handle": [0.2325, 0.0, 0.1], "max_travel": 0.32}
    return SceneObject("drawer_0", "drawer", mesh, dof="slide", axis=np.array([1.0, 0.0, 0.0]), dynamic=True,
                       meta=meta)


def keyboard() -> SceneObject:
    mesh = trimesh.creation.box(bounds=[[-0.07, -0.22, 0.0], [0.07, 0.22, 0.025]])
    meta = {"size": [0.14, 0.44, 0.025], "press_points": [[0.0, -0.1, 0.025], [0.0, 0.1, 0.025]],
            "grasp_point": [0.0, 0.0, 0.025], "grasp_axis": [0.0, 0.0, -1.0]}
    return SceneObject("keyboard_0", "keyboard", mesh, dof="free", dynamic=True, meta=meta)


def mouse() -> SceneObject:
    mesh = trimesh.creation.box(bounds=[[-0.05, -0.03, 0.0], [0.05, 0.03, 0.035]])
    meta = {"grip_point": [0.01, 0.0, 0.035], "grasp_point": [0.01, 0.0, 0.035], "grasp_axis": [0.0, 0.0, -1.0]}
    return SceneObject("mouse_0", "mouse", mesh, dof="free", dynamic=True, meta=meta)


def chair() -> SceneObject:
    seat = trimesh.creation.box(bounds=[[-0.22, -0.23, 0.40], [0.22, 0.23, 0.45]])
    back = trimesh.creation.box(bounds=[[-0.22, -0.22, 0.45], [-0.18, 0.22, 0.90]])
    meta = {"size": [0.44, 0.46, 0.9], "push_handles": [[-0.2, -0.14, 0.9], [-0.2, 0.14, 0.9]]}
    return SceneObject("chair_0", "chair", trimesh.util.concatenate([seat, back]), dof="slide", dynamic=True,
                       meta=meta)


def check_motion(m: Motion, max_step: float = 0.05, joints: list[int] | None = None) -> np.ndarray:
    """Common invariants; returns joints."""
    J = m.joints()
    assert np.abs(bone_lengths(J) - np.linalg.norm(OFF[1:], axis=1)).max() < 1e-9
    step = np.linalg.norm(np.diff(J, axis=0), axis=-1)
    assert step[:, joints if joints is not None else slice(None)].max() < max_step
    assert m.actions
    for a in m.actions:
        assert a.name in SYNTH_ACTIONS and 0 <= a.start < a.end <= m.num_frames  # half-open
    for name, tr in m.objects.items():
        assert tr.shape == (m.num_frames, 4, 4) and np.isfinite(tr).all()
        assert np.linalg.norm(np.diff(tr[:, :3, 3], axis=0), axis=1).max() < max_step
    for j, g in m.grasp.items():
        assert j in (hands.WRIST["left"], hands.WRIST["right"]) and g.shape == (m.num_frames,) and g.dtype == bool
    return J


def surface_distance(obj: SceneObject, pose: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return trimesh.proximity.closest_point(obj.world_mesh(pose), pts)[1]


def rigid_error(m: Motion, side: str, name: str, frames: np.ndarray) -> float:
    H = hands.hand_transform(m, side)[frames]
    rel = np.linalg.inv(H) @ m.objects[name][frames]
    return float(np.abs(rel - rel[0]).max())


@pytest.fixture(scope="module")
def carry_chain():
    rng = np.random.default_rng(3)
    obj = bottle()
    pose = pose_xyz_yaw(0.45, -0.12, 0.75, 2.0)
    b1 = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("pick_up", rng), rng)
    m1, hold = hands.pick_up(b1, obj, pose, "right", rng)
    walk = locomotion.walk(np.array([[0.0, 0.0], [1.2, 0.4]]), OFF, rng, speed=0.8, start_yaw=0.0, end_yaw=0.0)
    m2 = hands.carry(walk, hold)
    b3 = locomotion.stand(OFF, walk.root[-1, :2], 0.0, hands.nominal_frames("drink", rng), rng)
    m3 = hands.drink(b3, hold, obj, rng)
    b4 = locomotion.stand(OFF, walk.root[-1, :2], 0.0, hands.nominal_frames("put_down", rng), rng)
    target = pose_xyz_yaw(walk.root[-1, 0] + 0.45, walk.root[-1, 1] - 0.1, 0.72, 0.3)
    m4 = hands.put_down(b4, hold, target, rng, exact_yaw=True)
    return obj, pose, target, hold, [m1, m2, m3, m4]


def test_pick_up_contact_at_grasp_frames(carry_chain):
    obj, pose, _, _, (m1, *_) = carry_chain
    J = check_motion(m1)
    g = m1.grasp[hands.WRIST["right"]]
    g0 = int(np.flatnonzero(g)[0])
    assert [a.name for a in m1.actions] == ["reach", "grasp", "pick_up", "carry"]
    assert m1.actions[0].end == g0 + 1  # half-open: reach runs up to and including the grasp frame
    palm = hands.palm_points(J)[:, 1]
    # The object has not moved up to the grasp frame.
    assert np.allclose(m1.objects[obj.name][:g0 + 1], pose)
    # Palm on the (rotationally equivalent) grasp point: right height, PALM_GAP off the side.
    local = (np.linalg.inv(pose) @ np.r_[palm[g0], 1.0])[:3]
    gp = np.array(obj.meta["grasp_point"])
    assert abs(local[2] - gp[2]) < 0.02
    assert abs(np.hypot(local[0], local[1]) - np.hypot(gp[0], gp[1]) - hands.PALM_GAP) < 0.005
    # On every grasp frame the palm stays within 3 cm of the held object's surface.
    sd = np.array([surface_distance(obj, m1.objects[obj.name][t], palm[t][None])[0] for t in np.flatnonzero(g)[::4]])
    assert sd.max() < 0.03
    # The object leaves its support upwards after the grasp.
    assert m1.objects[obj.name][-1, 2, 3] > pose[2, 3] + 0.1


def test_carried_object_moves_rigidly(carry_chain):
    obj, _, target, hold, ms = carry_chain
    for m in ms:
        g = m.grasp[hands.WRIST["right"]]
        assert g.any()
        assert rigid_error(m, "right", obj.name, g) < 1e-9
    # put_down: the object ends exactly at the target and stays after the release.
    m4 = ms[-1]
    assert np.allclose(m4.objects[obj.name][-1], target, atol=1e-6)
    g = m4.grasp[hands.WRIST["right"]]
    assert not g[-1] and g[0]
    # The object stays upright while carried (drink aside).
    for m in ms[:2]:
        z = m.objects[obj.name][:, :3, 2]
        assert z[:, 2].min() > np.cos(np.radians(20))


def test_chain_is_continuous(carry_chain):
    _, _, _, _, ms = carry_chain
    full = concat_motions(ms)
    J = check_motion(full, joints=UPPER)  # walking feet swing faster than 5 cm / frame
    assert len(full.objects) == 1
    assert {a.name for a in full.actions} >= {"reach", "grasp", "pick_up", "carry", "drink", "put_down"}
    # Drinking brings the object's top to the mouth region (within 20 cm of the head joint).
    m3 = ms[2]
    mid = m3.num_frames // 2
    top = m3.objects["bottle_0"][mid] @ np.array([0, 0, 0.22, 1.0])
    assert np.linalg.norm(top[:3] - m3.joints()[mid, JOINT_INDEX["head"]]) < 0.2
    assert J.shape[0] == full.num_frames


def test_reach_grasp_flat_object_and_phone_call():
    rng = np.random.default_rng(7)
    obj = phone()
    pose = pose_xyz_yaw(0.42, -0.1, 0.74, 0.6)
    base = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("reach_grasp", rng), rng)
    m = hands.reach_grasp(base, obj, pose, "right", rng)
    J = check_motion(m)
    g = m.grasp[hands.WRIST["right"]]
    palm = hands.palm_points(J)[g, 1]
    gp = (pose @ np.r_[obj.meta["grasp_point"], 1.0])[:3]
    assert np.linalg.norm(palm - gp, axis=1).max() < 0.02
    assert surface_distance(obj, pose, palm).max() < 0.03
    assert np.allclose(m.objects[obj.name], pose)  # touched, not moved
    assert [a.name for a in m.actions] == ["reach", "grasp"]
    # The arm is back at the base pose at the end.
    assert np.allclose(J[-1], base.joints()[-1], atol=1e-6)

    b1 = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("pick_up", rng), rng)
    m1, hold = hands.pick_up(b1, obj, pose, "right", rng)
    b2 = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("phone_call", rng), rng)
    m2 = hands.phone_call(b2, hold, obj, rng)
    J2 = check_motion(m2)
    assert np.abs(J2[0] - m1.joints()[-1]).max() < 1e-6
    assert rigid_error(m2, "right", obj.name, np.ones(m2.num_frames, dtype=bool)) < 1e-9
    mid = m2.num_frames // 2
    c = (m2.objects[obj.name][mid] @ np.r_[obj.mesh.bounds.mean(0), 1.0])[:3]
    rel = c - J2[mid, JOINT_INDEX["head"]]
    assert 0.07 < np.linalg.norm(rel) < 0.15 and rel[1] < -0.05  # beside the head, on the right


def test_door_opens_wide_with_the_hand_on_the_handle():
    rng = np.random.default_rng(11)
    d = door()
    closed = pose_xyz_yaw(2.0, 1.0, 0.0, np.pi / 2)
    st = hands.door_stance(OFF, d, closed)
    assert 0.8 <= st.reach <= d.meta["max_angle"]  # a useful opening, not a crack
    angle = 0.9 * st.reach
    m = hands.open_door(OFF, d, closed, angle, rng, st)
    m2 = hands.close_door(OFF, d, closed, angle, rng, st)
    hinge = (closed @ np.r_[d.hinge_point, 1.0])[:3]
    for mm, a0, a1 in ((m, 0.0, angle), (m2, angle, 0.0)):
        J = check_motion(mm, joints=UPPER)  # stepping feet swing faster than 5 cm / frame
        tr = mm.objects[d.name]
        rel = np.linalg.inv(closed) @ tr
        ang = np.arctan2(rel[:, 1, 0], rel[:, 0, 0]) * d.meta["open_sign"]
        assert ang.min() >= -1e-9 and ang.max() <= d.meta["max_angle"] + 1e-9
        assert abs(ang[0] - a0) < 1e-9 and abs(ang[-1] - a1) < 1e-9
        assert np.all(np.diff(ang) * np.sign(a1 - a0) >= -1e-9)  # monotonic swing
        # The hinge point does not move; the leaf swings towards the person's side (+x of the door).
        hp = (tr @ np.r_[d.hinge_point, 1.0])[:, :3]
        assert np.abs(hp - hp[0]).max() < 1e-9
        free = (tr @ np.r_[0.0, -d.meta["width"] / 2, 1.0, 1.0])[:, :3]
        assert ((free - hinge) @ closed[:3, 0]).max() > 0.5
        g = mm.grasp[hands.WRIST[st.side]]
        handle = (tr @ np.r_[d.meta["handle"], 1.0])[:, :3]
        palm = hands.palm_points(J)[:, 0 if st.side == "left" else 1]
        assert g.sum() > 10 and g[np.argmax(np.abs(ang - a0) > 0.01)]  # holding it while it swings
        assert np.linalg.norm(palm[g] - handle[g], axis=1).max() < 0.05
        # Starts and ends in the canonical standing states of the path's two ends.
        for f, pos in ((0, st.pos if a0 == 0 else st.at(angle)), (-1, st.pos if a1 == 0 else st.at(angle))):
            r0, p0 = standing_state(OFF, pos, st.yaw)
            np.testing.assert_allclose(mm.root[f], p0, atol=1e-9)
            np.testing.assert_allclose(mm.rot[f], r0, atol=1e-9)
        # The body (arms aside) keeps clear of the leaf's box at every frame.
        body = [j for j in range(24) if j not in ARM_JOINTS]
        loc = np.einsum("tij,tkj->tki", np.linalg.inv(tr)[:, :3, :3], J[:, body]) + np.linalg.inv(tr)[:, None, :3, 3]
        lo, hi = d.mesh.bounds
        gap = np.linalg.norm(np.maximum(np.maximum(lo - loc, loc - hi), 0.0), axis=-1)
        assert (gap > JOINT_RADIUS[body] - 0.015).all()
        # Feet planted while the hand is on the handle except for the short steps (flat contact).
        ank = J[:, [JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"]]]
        for f in range(2):
            c = mm.foot_contact[:, f]
            d_ank = np.linalg.norm(np.diff(ank[:, f, :2], axis=0), axis=1)
            assert d_ank[c[1:] & c[:-1]].max() < 1e-6
        assert mm.actions[0].name == ("open_door" if a1 > a0 else "close_door")
    # The person steps back while pulling: the opened door stands where the person stood.
    assert np.linalg.norm(st.open_pos - st.pos) > 0.2
    with pytest.raises(ValueError, match="door angle"):
        hands.open_door(OFF, d, closed, st.reach + 0.1, rng, st)


@pytest.mark.parametrize("z", [0.3, 0.6])
def test_drawer_travel_limits_and_hand_on_handle(z):
    rng = np.random.default_rng(5)
    dr = drawer()
    closed = pose_xyz_yaw(-1.0, 0.5, z, 0.4)
    st = hands.drawer_stance(OFF, dr, closed)
    assert 0.0 < st.reach <= dr.meta["max_travel"]
    frames = int(1.3 * hands.nominal_frames("open_drawer", rng))
    m = hands.open_drawer(locomotion.stand(OFF, st.pos, st.yaw, frames, rng), dr, closed, st.reach, rng, side=st.side)
    J = check_motion(m)
    tr = m.objects[dr.name]
    rel = np.linalg.inv(closed) @ tr
    travel = rel[:, 0, 3]
    assert travel.min() >= -1e-9 and travel.max() <= dr.meta["max_travel"] + 1e-9
    assert np.abs(rel[:, 1:3, 3]).max() < 1e-9 and np.allclose(rel[:, :3, :3], np.eye(3))
    assert abs(travel[-1] - st.reach) < 1e-9
    g = m.grasp[hands.WRIST[st.side]]
    handle = (tr @ np.r_[dr.meta["handle"], 1.0])[:, :3]
    palm = hands.palm_points(J)[:, 0 if st.side == "left" else 1]
    assert np.linalg.norm(palm[g] - handle[g], axis=1).max() < 0.03
    m2 = hands.close_drawer(locomotion.stand(OFF, st.pos, st.yaw, frames, rng), dr, closed, st.reach, rng, side=st.side)
    check_motion(m2)
    assert abs((np.linalg.inv(closed) @ m2.objects[dr.name][-1])[0, 3]) < 1e-9


@pytest.fixture(scope="module")
def seated():
    seat = np.array([0.9, 0.0, 0.46])
    yaw = np.pi  # facing -x, towards the desk at x ~ 0.3
    stand = np.array([0.7, 0.0])
    return seat, yaw, stand


def test_typing(seated):
    rng = np.random.default_rng(2)
    seat, yaw, stand = seated
    kb = keyboard()
    pose = pose_xyz_yaw(0.32, 0.0, 0.74, 0.0)
    base = posture.sit(OFF, seat, yaw, stand, hands.nominal_frames("type", rng), rng)
    m = hands.type_keyboard(base, kb, pose, rng)
    J = check_motion(m)
    assert np.allclose(m.objects[kb.name], pose)
    pts = np.array([(pose @ np.r_[p, 1.0])[:3] for p in kb.meta["press_points"]])
    P = hands.palm_points(J)
    for k, side in enumerate(("left", "right")):
        g = m.grasp[hands.WRIST[side]]
        assert g.sum() > 30
        d = np.linalg.norm(P[g, k] - pts[k], axis=1)
        assert d.max() < 0.03
        assert np.ptp(P[g, k, 2]) > 0.002  # the fingers tap
    assert np.allclose(J[[0, -1]], base.joints()[[0, -1]], atol=1e-6)


def test_use_mouse_stays_on_desk_and_follows_hand(seated):
    rng = np.random.default_rng(4)
    seat, yaw, stand = seated
    ms = mouse()
    pose = pose_xyz_yaw(0.32, 0.33, 0.74, 0.0)  # facing -x, the sitter's right is +y
    base = posture.sit(OFF, seat, yaw, stand, hands.nominal_frames("use_mouse", rng), rng)
    m = hands.use_mouse(base, ms, pose, rng)
    check_motion(m)
    g = m.grasp[hands.WRIST["right"]]
    assert g.sum() > 30
    tr = m.objects[ms.name]
    assert np.abs(tr[:, 2, 3] - pose[2, 3]).max() < 1e-6  # stays on the surface
    assert np.allclose(tr[:, :3, 2], [0, 0, 1], atol=1e-6)
    assert np.linalg.norm(tr[:, :2, 3] - pose[:2, 3], axis=1).max() <= 0.05
    assert np.linalg.norm(tr[:, :2, 3] - pose[:2, 3], axis=1).max() > 0.003
    assert rigid_error(m, "right", ms.name, g) < 1e-9
    assert [a.name for a in m.actions] == ["use_mouse"]


@pytest.mark.parametrize("kind", ["push", "pull"])
def test_push_pull_chair(kind):
    rng = np.random.default_rng(9)
    ch = chair()
    pose = pose_xyz_yaw(0.5, 0.5, 0.0, 0.7)
    dist = 0.6
    m = (hands.push if kind == "push" else hands.pull)(OFF, ch, pose, dist, rng)
    J = check_motion(m, joints=UPPER)
    tr = m.objects[ch.name]
    assert np.allclose(tr[0], pose)
    assert np.allclose(tr[:, :3, :3], pose[:3, :3]) and np.allclose(tr[:, 2, 3], 0.0)
    move = tr[-1, :3, 3] - pose[:3, 3]
    assert abs(np.linalg.norm(move) - dist) < 1e-6
    face = pose[:3, 0]  # person behind the backrest faces the chair's +x
    assert np.dot(move, face) * (1 if kind == "push" else -1) > 0.99 * dist
    pos, yaw = hands.push_stance(OFF, ch, pose)
    assert np.allclose(m.root[0, :2], pos, atol=1e-6)
    handles = np.asarray(ch.meta["push_handles"])
    P = hands.palm_points(J)
    for k, side in enumerate(("left", "right")):
        g = m.grasp[hands.WRIST[side]]
        assert g.sum() > 20
        h = handles[np.argsort(-handles[:, 1])][k]
        hw = (tr[g] @ np.r_[h, 1.0])[:, :3]
        assert np.linalg.norm(P[g, k] - hw, axis=1).max() < 0.03
    assert {a.name for a in m.actions} <= {"reach", kind}


def test_bad_inputs_and_determinism():
    rng = np.random.default_rng(0)
    obj = bottle()
    pose = pose_xyz_yaw(0.45, -0.1, 0.75, 0.0)
    base = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("pick_up", np.random.default_rng(0)), rng)
    with pytest.raises(ValueError, match="side"):
        hands.pick_up(base, obj, pose, "middle", rng)
    with pytest.raises(ValueError, match="too short"):
        hands.pick_up(Motion(base.rot[:5], base.root[:5], OFF), obj, pose, "right", rng)
    with pytest.raises(hands.OutOfReach):
        hands.pick_up(base, obj, pose_xyz_yaw(3.0, 0.0, 0.75, 0.0), "right", rng)
    bare = SceneObject("box", "box", trimesh.creation.box(extents=[0.1, 0.1, 0.1]), dof="free")
    with pytest.raises(ValueError, match="grasp_point"):
        hands.pick_up(base, bare, pose, "right", rng)
    with pytest.raises(ValueError, match="4, 4"):
        hands.pick_up(base, obj, np.eye(3), "right", rng)
    with pytest.raises(ValueError, match="door angle"):
        st = hands.DoorStance(pos=np.array([0.5, 0.3]), yaw=np.pi, side="right", reach=1.0,
                              open_pos=np.array([1.0, 0.3]))
        hands.open_door(OFF, door(), np.eye(4), 2.0, rng, st)
    with pytest.raises(ValueError, match="unknown primitive"):
        hands.nominal_frames("juggle", rng)
    a, _ = hands.pick_up(base, obj, pose, "right", np.random.default_rng(1))
    b, _ = hands.pick_up(base, obj, pose, "right", np.random.default_rng(1))
    assert np.array_equal(a.rot, b.rot) and np.array_equal(a.objects["bottle_0"], b.objects["bottle_0"])


def test_slerp_track_is_continuous_through_180_degrees():
    th = np.radians(np.linspace(170.0, 190.0, 21))
    B = np.zeros((21, 3, 3))
    B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1], B[:, 2, 2] = np.cos(th), -np.sin(th), np.sin(th), np.cos(th), 1
    A = np.broadcast_to(np.eye(3), (21, 3, 3))
    half = hands.slerp_track(A, B, np.full(21, 0.5))
    step = np.linalg.norm(np.diff(half, axis=0), axis=(1, 2))
    assert step.max() < 0.05  # ~0.5 deg per frame, no flip
    assert np.allclose(hands.slerp_track(A, B, np.ones(21)), B, atol=1e-9)
    assert np.allclose(hands.slerp_track(A, B, np.zeros(21)), A, atol=1e-12)


def test_put_down_keeps_carried_yaw_unless_exact():
    rng = np.random.default_rng(12)
    obj = phone()
    pose = pose_xyz_yaw(0.42, -0.1, 0.74, 0.6)
    b1 = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("pick_up", rng), rng)
    m1, hold = hands.pick_up(b1, obj, pose, "right", rng)
    b2 = locomotion.stand(OFF, np.zeros(2), 0.0, hands.nominal_frames("put_down", rng), rng)
    target = pose_xyz_yaw(0.45, -0.25, 0.74, 2.5)
    m2 = hands.put_down(b2, hold, target, rng)
    check_motion(m2)
    end = m2.objects[obj.name][-1]
    assert np.allclose(end[:3, 3], target[:3, 3], atol=1e-6)  # placed where asked
    carried = m1.objects[obj.name][-1]
    yaw = lambda p: np.arctan2(p[1, 0], p[0, 0])  # noqa: E731
    assert abs(np.angle(np.exp(1j * (yaw(end) - yaw(carried))))) < 1e-6  # as carried, not 2.5 rad
    assert np.allclose(end[:3, 2], [0, 0, 1], atol=1e-6)


def test_phase_registry_covers_every_primitive():
    """One registry times every hand primitive: each has its flexible phase, phases cover the base
    exactly and in order, and a base under half the natural length is refused."""
    from trumans.synth.hands.timing import FLEX, phases

    assert set(hands.PHASES) == set(FLEX)
    rng = np.random.default_rng(0)
    for kind, spec in hands.PHASES.items():
        assert FLEX[kind] in spec and all(0 < lo <= hi for lo, hi in spec.values())
        T = hands.nominal_frames(kind, rng)
        ph = phases(kind, T, rng, 30.0)
        assert list(ph) == list(spec)
        edges = [b for b in ph.values()]
        assert edges[0][0] == 0 and edges[-1][1] == T - 1
        assert all(a[1] == b[0] for a, b in zip(edges, edges[1:]))  # contiguous
        with pytest.raises(ValueError, match="too short"):
            phases(kind, max(2, T // 8), rng, 30.0)
