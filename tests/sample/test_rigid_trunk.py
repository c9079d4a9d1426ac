"""The bone projection keeps the trunk's rigid pieces rigid (issue 34 point 2): hip width and collar
spacing stay the body's, bone lengths stay exact, and a rigid-skeleton fit reproduces the joints."""
import numpy as np

from trumans.ik.fit import fit_error, fit_rotations
from trumans.sample.cleanup.bones import RIGID_PIECES, bone_lengths_of, project_bones
from trumans.skeleton import JOINT_INDEX, REST_JOINTS


def _wobbly(T=30, seed=0):
    """The rest pose with every joint jittered by up to 3 cm per frame (hip width and collar
    spacing swing by centimetres, as the network's do), walking forward."""
    rng = np.random.default_rng(seed)
    P = np.repeat(REST_JOINTS[None], T, 0) + rng.normal(0, 0.015, (T, 24, 3))
    P[..., 0] += np.linspace(0, 1.0, T)[:, None]
    return P


def test_rigid_pieces_are_the_pelvis_and_spine3():
    assert RIGID_PIECES == {JOINT_INDEX["pelvis"]: (1, 2, 3), JOINT_INDEX["spine3"]: (12, 13, 14)}


def test_rigid_trunk_keeps_shape_lengths_and_is_reproduced_by_a_skeleton():
    P = _wobbly()
    lengths = bone_lengths_of(REST_JOINTS)
    out = project_bones(P, lengths, rigid_trunk=True).astype(np.float64)
    np.testing.assert_allclose(bone_lengths_of(out), np.broadcast_to(lengths, (len(P), 24)), atol=2e-6)
    for p, kids in RIGID_PIECES.items():
        for a in kids:
            for b in kids:
                d = np.linalg.norm(out[:, a] - out[:, b], axis=-1)
                ref = np.linalg.norm(REST_JOINTS[a] - REST_JOINTS[b])
                np.testing.assert_allclose(d, ref, atol=2e-6)  # the rest shape at the body's lengths
    loose = project_bones(P, lengths).astype(np.float64)
    hip = np.linalg.norm(loose[:, 1] - loose[:, 2], axis=-1)
    assert np.ptp(hip) > 0.01  # without it the hip width swings
    fit = {}
    for name, joints in (("rigid", out), ("loose", loose)):
        rot, root, off = fit_rotations(joints, refine_steps=30)
        fit[name] = fit_error(joints, rot, root, off)["max"]
    assert fit["rigid"] < 1e-4 and fit["loose"] > 5e-3  # m: a skeleton reproduces only the rigid body
    # the rigid pieces are turned, not bent: an already rigid body comes back unchanged
    np.testing.assert_allclose(project_bones(out, lengths, rigid_trunk=True), out, atol=2e-6)
