"""joint_centre_inside_cm works in each object's frame, tests inside-ness first and finds closest points
only for the joints inside (issue 38); it must equal the deepest of SceneDistance.query's signed
distances on the world meshes, as before (to the float32 rounding of the ray casting's coordinates)."""
import numpy as np
import pytest
import trimesh

from trumans.eval.metrics import joint_centre_inside_cm
from trumans.scenes.distance import SceneDistance
from trumans.scenes.scene import Scene, SceneObject


def _reference(joints: np.ndarray, scene: Scene, names: list[str]) -> float:
    pts = joints.reshape(-1, 3)
    meshes = {n: scene.objects[n].world_mesh() for n in names}
    near = np.zeros(len(pts), bool)
    for m in meshes.values():
        near |= np.all((pts >= m.bounds[0]) & (pts <= m.bounds[1]), axis=1)
    if not near.any():
        return 0.0
    s = SceneDistance(meshes).query(pts[near]).signed
    return float(max(0.0, -float(s.min())) * 100.0)


def test_matches_full_signed_distance_query():
    pose = trimesh.transformations.rotation_matrix(0.7, [0, 0, 1])  # a turned chair
    pose[:3, 3] = [1.0, 0.5, 0.3]
    box_pose = np.eye(4)
    box_pose[:3, 3] = [0.8, 0.6, 0.5]
    seat = trimesh.util.concatenate([trimesh.creation.box((0.5, 0.5, 0.1)),  # two overlapping boxes
                                     trimesh.creation.box((0.1, 0.5, 0.6), trimesh.transformations.translation_matrix((0.2, 0, 0.25)))])
    scene = Scene(name="s", objects={"chair": SceneObject("chair", "chair", seat, pose=pose),
                                     "box": SceneObject("box", "table", trimesh.creation.box((0.4, 0.4, 0.4)), pose=box_pose)})
    rng = np.random.default_rng(0)
    for k in range(6):
        joints = np.array([1.0, 0.5, 0.4]) + rng.normal(0, 0.25, (30, 24, 3))
        names = [["chair"], ["box"], ["chair", "box"]][k % 3]
        got = joint_centre_inside_cm(joints, scene, names)
        assert got == pytest.approx(_reference(joints, scene, names), abs=1e-4)
        if k < 3:
            assert got > 0.5  # some joint centres are inside: the deferred closest-point path ran
    far = np.full((4, 24, 3), 5.0)
    assert joint_centre_inside_cm(far, scene, ["chair"]) == 0.0
    # a box-corner point inside the bounds but outside the solid: inside test says no, figure 0
    corner = pose[:3, :3] @ [-0.2, 0.0, 0.4] + pose[:3, 3]  # above the seat, in front of the back
    assert joint_centre_inside_cm(np.broadcast_to(corner, (1, 24, 3)).copy(), scene, ["chair"]) == 0.0


def test_scaled_pose_falls_back_to_world_meshes():
    pose = np.diag([2.0, 1.0, 1.0, 1.0])  # not rigid: distances change with it
    scene = Scene(name="s", objects={"box": SceneObject("box", "table", trimesh.creation.box((0.4, 0.4, 0.4)), pose=pose)})
    joints = np.zeros((1, 24, 3))
    joints[0, :, 0] = np.linspace(-0.5, 0.5, 24)
    got = joint_centre_inside_cm(joints, scene, ["box"])
    assert got == pytest.approx(_reference(joints, scene, ["box"]), abs=1e-4)
    assert got == pytest.approx(20.0, abs=1.0)  # the centre lies 0.2 m under the top and bottom faces
