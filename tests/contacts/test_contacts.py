"""The TRUMANS contact rule on joints (trumans.contacts.rule), on analytic cases."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from trumans.scenes.distance import SceneDistance
from trumans.scenes.scene import Scene, SceneObject
from trumans.contacts.rule import FLOOR_NAME, JOINT_RADIUS, ContactScene, joint_contacts, outward_directions
from trumans.skeleton import JOINT_INDEX, REST_JOINTS, forward_kinematics, rest_offsets

LW = JOINT_INDEX["left_wrist"]
TOP = 1.0  # box top face height


def _box_scene() -> SceneDistance:
    box = trimesh.creation.box((1.0, 1.0, TOP))
    box.apply_translation([2.0, 0.0, TOP / 2])
    return SceneDistance({"box": box})


def _posed(n: int, root_rot: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """n rest-pose frames (T-pose, palms down): joints (n, 24, 3) and global rotations."""
    rot = np.tile(np.eye(3), (n, 24, 1, 1))
    if root_rot is not None:
        rot[:, 0] = root_rot
    return forward_kinematics(rot, np.tile(rest_offsets()[0], (n, 1)))


def _hand_at(joints: np.ndarray, G: np.ndarray, t: int, pos) -> None:
    """Translate frame t so the left wrist sits at ``pos`` (keeps the pose)."""
    joints[t] += np.asarray(pos) - joints[t, LW]


def test_palm_facing_box_one_cm_away_is_contact():
    J, G = _posed(1)
    _hand_at(J, G, 0, [2.0, 0.0, TOP + JOINT_RADIUS[LW] + 0.01])  # palm (down) 1 cm above the top
    r = joint_contacts(J, _box_scene(), threshold=0.03, global_rot=G)
    assert r.contact[0, LW]
    assert r.names[r.object_index[0, LW]] == "box"
    assert r.distance[0, LW] == pytest.approx(JOINT_RADIUS[LW] + 0.01, abs=1e-5)
    np.testing.assert_allclose(r.closest[0, LW], [2.0, 0.0, TOP], atol=1e-5)


def test_palm_facing_away_is_no_contact_but_beyond_threshold_also_not():
    flip = Rotation.from_euler("x", 180, degrees=True).as_matrix()  # palm up, fingers horizontal
    J, G = _posed(2, flip)
    _hand_at(J, G, 0, [2.0, 0.0, TOP + JOINT_RADIUS[LW] + 0.01])
    J2, G2 = _posed(1)
    _hand_at(J2, G2, 0, [2.0, 0.0, TOP + JOINT_RADIUS[LW] + 0.05])  # facing, but 5 cm > threshold
    J[1], G[1] = J2[0], G2[0]
    r = joint_contacts(J, _box_scene(), threshold=0.03, global_rot=G)
    assert not r.contact[0, LW]
    assert not r.contact[1, LW]
    assert r.object_index[0, LW] == -1


def test_inside_is_contact_whatever_the_direction():
    flip = Rotation.from_euler("x", 180, degrees=True).as_matrix()
    J, G = _posed(1, flip)
    _hand_at(J, G, 0, [2.0, 0.0, TOP - 0.1])
    r = joint_contacts(J, _box_scene(), global_rot=G)
    assert r.contact[0, LW] and r.distance[0, LW] < 0


def test_standing_feet_touch_the_floor_plane_only():
    J, G = _posed(1)
    r = joint_contacts(J, _box_scene(), global_rot=G)
    feet = [JOINT_INDEX[n] for n in ("left_foot", "right_foot", "left_ankle", "right_ankle")]
    assert r.contact[0, feet].all()
    assert all(r.names[i] == FLOOR_NAME for i in r.object_index[0, feet])
    others = [j for j in range(24) if j not in feet]
    assert not r.contact[0, others].any()
    assert not joint_contacts(J, _box_scene(), floor=False).contact[0, feet].any()


def test_outward_directions_are_unit_and_palm_follows_rotation():
    J, G = _posed(1)
    d = outward_directions(J, G)
    n = np.linalg.norm(d, axis=-1)
    assert np.all((np.abs(n - 1) < 1e-9) | (n == 0))
    np.testing.assert_allclose(d[0, LW, 0], [0, 0, -1], atol=1e-9)  # palm down in the T-pose
    np.testing.assert_allclose(d[0, JOINT_INDEX["spine2"], 0], [-1, 0, 0], atol=0.05)  # back = -x


def test_contact_scene_follows_a_moving_dynamic_object():
    cup = trimesh.creation.cylinder(radius=0.04, height=0.12)
    obj = SceneObject("cup0", "cup", cup, pose=np.eye(4), dof="free", dynamic=True)
    scene = Scene("s", static={}, objects={"cup0": obj})
    J, G = _posed(2)
    hand = J[:, LW].copy()
    poses = np.tile(np.eye(4), (2, 1, 1))
    poses[0, :3, 3] = [5.0, 5.0, 0.06]  # far away on frame 0
    poses[1, :3, 3] = hand[1] - np.array([0, 0, JOINT_RADIUS[LW] + 0.01 + 0.06])  # under the palm on frame 1
    cs = ContactScene(scene)
    r = joint_contacts(J, cs, global_rot=G, object_poses={"cup0": poses})
    assert not r.contact[0, LW] and r.contact[1, LW]
    assert r.names[r.object_index[1, LW]] == "cup0"
    assert r.distance[1, LW] == pytest.approx(JOINT_RADIUS[LW] + 0.01, abs=1e-4)


def test_bad_inputs():
    sd = _box_scene()
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        joint_contacts(np.zeros((5, 23, 3)), sd)
    with pytest.raises(ValueError, match="threshold"):
        joint_contacts(REST_JOINTS[None], sd, threshold=-0.1)
    with pytest.raises(ValueError, match="global_rot"):
        joint_contacts(REST_JOINTS[None], sd, global_rot=np.zeros((1, 24, 3)))
    with pytest.raises(ValueError, match="SceneDistance or ContactScene"):
        joint_contacts(REST_JOINTS[None], {"box": None})
    cs = ContactScene(Scene("s", static={"b": trimesh.creation.box((1, 1, 1))}))
    with pytest.raises(ValueError, match="not dynamic objects"):
        joint_contacts(REST_JOINTS[None], cs, object_poses={"nope": np.eye(4)[None]})


def test_open_mesh_keeps_its_contacts():
    """A non-watertight object (two faces missing) is still touched: its contacts are not dropped."""
    import trimesh

    from trumans.scenes.scene import Scene, SceneObject
    from trumans.contacts.rule import ContactScene, joint_contacts
    from trumans.skeleton import REST_JOINTS

    box = trimesh.creation.box((1.0, 1.0, 0.7))
    box.apply_translation([0, 0, 0.35])
    open_box = trimesh.Trimesh(box.vertices, box.faces[2:], process=False)
    assert not open_box.is_watertight
    scene = Scene("t", objects={"table_0": SceneObject("table_0", "table", open_box)})
    J = np.repeat(REST_JOINTS[None].astype(np.float64), 2, axis=0)
    J[:, :, 1] += 1.2
    J[:, 21] = [0.2, 0.1, 0.73]  # right wrist resting on the top
    r = joint_contacts(J, ContactScene(scene))
    assert r.contact[:, 21].all() and (r.object_index[:, 21] == r.names.index("table_0")).all()
