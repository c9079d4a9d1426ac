"""trumans.bvh: write/read round trips, the CMU excerpt, rotation-order conventions, bad inputs."""

import numpy as np
import pytest
import torch

from trumans.bvh import Y_UP_FROM_Z_UP, read_bvh, write_bvh
from trumans.importers.bvh import import_bvh
from trumans.importers.joint_maps import DEFAULT_JOINT_MAP, map_joints
from trumans.rotations import axis_angle_to_matrix, sixd_to_matrix, yaw_matrix
from trumans.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS, forward_kinematics, heading, rest_offsets

from helpers import CMU_WALK_BVH

torch.set_num_threads(1)

CMU = CMU_WALK_BVH
JI = JOINT_INDEX


def _plausible(T, seed=0, scale=0.35):
    """Random poses (as in test_ik): modest local rotations, random heading, pelvis near standing height."""
    rng = np.random.default_rng(seed)
    R = axis_angle_to_matrix(rng.normal(0, scale, (T, NUM_JOINTS, 3)))
    R[:, 0] = yaw_matrix(rng.uniform(-np.pi, np.pi, T)) @ R[:, 0]
    root = np.concatenate([rng.uniform(-3, 3, (T, 2)), rng.uniform(0.6, 1.0, (T, 1))], axis=1)
    return R, root


def _global(rot):
    """Local rotations (T, 24, 3, 3) -> global."""
    G = [rot[:, 0]]
    for j in range(1, NUM_JOINTS):
        G.append(G[PARENTS[j]] @ rot[:, j])
    return np.stack(G, 1)


# ------------------------------------------------------------------------------------ round trips

@pytest.mark.parametrize("fps", [30.0, 120.0])
def test_write_import_round_trip(tmp_path, fps):
    T = 40
    R, root = _plausible(T, seed=3)
    off = rest_offsets(np.random.default_rng(4).uniform(0.9, 1.1, NUM_JOINTS))
    J, _ = forward_kinematics(R, root, off)
    path = tmp_path / "clip.bvh"
    write_bvh(path, R, root, off, fps)

    bvh = read_bvh(path)
    assert sorted(bvh.names) == sorted(JOINT_NAMES) and bvh.num_frames == T
    assert bvh.fps == fps  # 1 / 0.00833333 snaps back to 120 exactly
    P_file, _ = bvh.forward_kinematics()  # y-up file axes: (X, Y, Z) = (left, up, forward)
    np.testing.assert_allclose(P_file[:, [bvh.index(n) for n in JOINT_NAMES]], J @ Y_UP_FROM_Z_UP.T, atol=1e-5)

    seq = import_bvh(path)
    assert seq.fps == fps and seq.num_frames == T
    assert np.abs(seq.joints - J).max() < 1e-3  # z-up restored, within 1 mm
    # our own skeleton: the file's rotations are kept (no IK fit) and reproduce the joints
    assert "ik_error_max" not in seq.extra
    R2 = sixd_to_matrix(seq.rotations.astype(np.float64))
    np.testing.assert_allclose(R2, R, atol=1e-4)
    np.testing.assert_allclose(seq.root_pos, root, atol=1e-5)
    J2, _ = forward_kinematics(R2, seq.root_pos.astype(np.float64), off)
    assert np.abs(J2 - J).max() < 1e-3
    np.testing.assert_allclose(seq.extra["offsets"][1:], off[1:], atol=1e-5)  # the file's bones, our axes


def test_import_z_up_keeps_file_axes(tmp_path):
    R, root = _plausible(5, seed=1)
    J, _ = forward_kinematics(R, root)
    write_bvh(tmp_path / "c.bvh", R, root, rest_offsets(), 30)
    seq = import_bvh(tmp_path / "c.bvh", up="z", unit_scale=1.0)  # (its "height" is now its depth)
    np.testing.assert_allclose(seq.joints, J @ Y_UP_FROM_Z_UP.T, atol=1e-4)  # taken as they are


def test_import_resamples(tmp_path):
    R, root = _plausible(31, seed=5, scale=0.2)
    J, _ = forward_kinematics(R, root)
    write_bvh(tmp_path / "c.bvh", R, root, rest_offsets(), 30)
    seq = import_bvh(tmp_path / "c.bvh", fps=10)
    assert seq.fps == 10 and seq.num_frames == 11  # same 1 s duration
    np.testing.assert_allclose(seq.joints, J[::3], atol=1e-4)  # output frames fall on input frames


@pytest.mark.parametrize("order, angles, expected", [
    # R = Rz(90) @ Rx(90) (channel order) maps the child's OFFSET (0, 0, 1) to (1, 0, 0); the
    # reverse product would give (0, -1, 0)
    ("Zrotation Xrotation", "90 90", [1.0, 0.0, 0.0]),
    ("Xrotation Zrotation", "90 90", [0.0, -1.0, 0.0]),
    ("Zrotation Zrotation", "45 45", [0.0, 0.0, 1.0]),  # a repeated axis composes
    ("Yrotation", "90", [1.0, 0.0, 0.0]),
])
def test_rotation_channel_order_analytic(tmp_path, order, angles, expected):
    n = len(order.split())
    text = (f"HIERARCHY\nROOT a\n{{\n\tOFFSET 0 0 0\n\tCHANNELS {3 + n} Xposition Yposition Zposition {order}\n"
            "\tJOINT b\n\t{\n\t\tOFFSET 0 0 1\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
            "\t\tEnd Site\n\t\t{\n\t\t\tOFFSET 0 0 1\n\t\t}\n\t}\n}\n"
            f"MOTION\nFrames: 1\nFrame Time: 0.1\n5 6 7 {angles} 0 0 0\n")
    (tmp_path / "t.bvh").write_text(text)
    P, _ = read_bvh(tmp_path / "t.bvh").forward_kinematics()
    np.testing.assert_allclose(P[0, 0], [5, 6, 7])  # position channels replace the root's OFFSET
    np.testing.assert_allclose(P[0, 1] - P[0, 0], expected, atol=1e-12)


# ------------------------------------------------------------------------------------ CMU excerpt

@pytest.fixture(scope="module")
def cmu():
    return import_bvh(CMU)


def test_cmu_joint_mapping():
    bvh = read_bvh(CMU)
    assert len(bvh.names) == 31 and bvh.num_frames == 480 and bvh.fps == 120
    src = map_joints(bvh.names)
    picked = {ours: bvh.names[i] for ours, i in src.items() if i is not None}
    assert picked["left_hip"] == "LeftHip" and picked["left_knee"] == "LeftKnee"
    assert picked["left_shoulder"] == "LeftShoulder" and picked["left_collar"] == "LeftCollar"
    assert picked["left_foot"] == "LeftToe" and picked["spine3"] == "Chest2"
    assert all(picked[k] in DEFAULT_JOINT_MAP[k] for k in picked)


def test_cmu_import_is_a_plausible_standing_walker(cmu):
    J = cmu.joints.astype(np.float64)
    assert J.shape == (480, 24, 3) and np.isfinite(J).all() and cmu.fps == 120
    # units (CMU, 0.0564444 m) and axes (y-up -> z-up) are right: standing at the start
    standing = J[:60]
    assert 0.8 < standing[:, JI["pelvis"], 2].mean() < 1.1
    legs = np.linalg.norm(J[0, JI["left_hip"]] - J[0, JI["left_ankle"]])
    assert 0.7 < legs < 1.0
    # head joint height; the CMU skeleton's torso is short (top of the head end site ~1.45 m for this
    # subject), so this is looser than a real stature
    assert 1.25 < standing[:, JI["head"], 2].mean() < 1.8
    assert (standing[:, JI["head"], 2] > standing[:, JI["neck"], 2]).all()
    # feet (toe-base joints) on the floor: the file's floor is z = 0, nothing goes through it
    feet = J[:, [JI["left_foot"], JI["right_foot"]], 2]
    assert 0.0 <= feet.min() < 0.05
    assert (standing[:, [JI["left_foot"], JI["right_foot"]], 2] < 0.1).all()
    assert abs(feet[:60, 0].mean() - feet[:60, 1].mean()) < 0.03  # both feet at the same height
    # not mirrored: the toes point along the heading (the left side is +y of forward)
    h0 = heading(standing).mean()
    fwd = np.array([np.cos(h0), np.sin(h0), 0.0])
    toe = standing[:, [JI["left_foot"], JI["right_foot"]]] - standing[:, [JI["left_ankle"], JI["right_ankle"]]]
    assert (toe @ fwd).mean() > 0.05
    # the walk moves the pelvis forward (along the initial heading) by several tens of cm
    d = (J[:, 0, :2] - J[0, 0, :2]) @ fwd[:2]
    assert d.max() > 0.3
    # ... and the take ends in the deep dip
    assert J[:, 0, 2].min() < 0.6


def test_cmu_rotations_reproduce_the_joints(cmu):
    J = cmu.joints.astype(np.float64)
    R = sixd_to_matrix(cmu.rotations.astype(np.float64))
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-5)
    # the rotations imply a rigid skeleton: each bone in its parent's fitted frame barely changes
    G = _global(R)
    bones = np.einsum("tjki,tjk->tji", G[:, PARENTS[1:]], J[:, 1:] - J[:, PARENTS[1:]])
    assert bones.std(0).max() < 0.01
    off = np.zeros((NUM_JOINTS, 3))
    off[1:] = bones.mean(0)
    J2, _ = forward_kinematics(R, cmu.root_pos.astype(np.float64), off)
    err = np.linalg.norm(J2 - J, axis=-1)
    assert err.mean() < 0.003 and err.max() < 0.02
    # the stored offsets go with the rotations
    J3, _ = forward_kinematics(R, cmu.root_pos.astype(np.float64), cmu.extra["offsets"].astype(np.float64))
    np.testing.assert_allclose(np.linalg.norm(J3 - J, axis=-1).max(), err.max(), atol=2e-3)
    # the stored fit error agrees with this check
    assert float(cmu.extra["ik_error_mean"]) < 0.003 and float(cmu.extra["ik_error_max"]) < 0.02
    assert abs(err.mean() - float(cmu.extra["ik_error_mean"])) < 5e-4


def test_cmu_resampled_to_30_fps(cmu):
    s30 = import_bvh(CMU, fps=30, refine_steps=0)
    assert s30.fps == 30 and s30.num_frames == 120  # 479 / 120 s of motion -> frames 0..119 at 30 fps
    np.testing.assert_allclose(s30.joints, cmu.joints[::4], atol=1e-5)
    assert s30.rotations.shape == (120, 24, 6)


# ------------------------------------------------------------------------------------ bad inputs

@pytest.fixture()
def small_bvh(tmp_path):
    R, root = _plausible(3, seed=2)
    path = tmp_path / "small.bvh"
    write_bvh(path, R, root, rest_offsets(), 30)
    return path


def _corrupt(path, text, name):
    p = path.parent / name
    p.write_text(text)
    return p


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.bvh does not exist"):
        import_bvh(tmp_path / "nope.bvh")
    with pytest.raises(ValueError, match="is a folder, not a file"):
        read_bvh(tmp_path)


def test_truncated_and_corrupt_files(small_bvh):
    text = small_bvh.read_text()
    head, motion = text.split("MOTION\n")
    rows = motion.strip().splitlines()  # Frames, Frame Time, 3 frames of 75 values
    cases = {
        "short_row": (head + "MOTION\n" + "\n".join(rows[:-1] + [" ".join(rows[-1].split()[:10])]),
                      r"frame 2 has 10 values but the hierarchy declares 75 channels"),
        "missing_rows": (head + "MOTION\n" + "\n".join(rows[:-1]), r"header says 3 frames but only 2 .*truncated"),
        "no_motion": (text[: len(text) // 3], r"no MOTION section; the file is truncated"),
        "no_frame_lines": (head + "MOTION\n", r"'Frames: N' and 'Frame Time: dt'.*truncated"),
        "non_numeric": (head + "MOTION\n" + "\n".join(rows[:2] + [rows[2].replace(" ", " abc ", 1)] + rows[3:]),
                        r"non-numeric value"),
        "nan": (head + "MOTION\n" + "\n".join(rows[:2] + ["nan " + rows[2].split(" ", 1)[1]] + rows[3:]), r"NaN"),
        "zero_frame_time": (head + "MOTION\n" + "\n".join([rows[0], "Frame Time: 0"] + rows[2:]),
                            r"Frame Time must be positive"),
        "not_bvh": ("hello\n", r"must start with HIERARCHY"),
        "wrong_channel_count": (text.replace("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 4 Zrotation Xrotation Yrotation", 1),
                                r"joint '\w+' declares CHANNELS 4 .*count must match"),
        "bad_offset": (text.replace("\tOFFSET ", "\tOFFSET oops ", 1), r"OFFSET must be 3 numbers, got 'oops"),
    }
    for name, (bad, pattern) in cases.items():
        p = _corrupt(small_bvh, bad, f"{name}.bvh")
        with pytest.raises(ValueError, match=pattern) as err:
            import_bvh(p)
        assert str(p) in str(err.value), name  # the message names the file
    p = _corrupt(small_bvh, head + "MOTION\nFrames: 0\nFrame Time: 0.0333333\n", "empty.bvh")
    with pytest.raises(ValueError, match="holds no frames"):
        import_bvh(p)


def test_unmappable_joint_names(small_bvh):
    renames = {n: f"bone{i:02d}" for i, n in enumerate(JOINT_NAMES)}
    text = small_bvh.read_text()
    for ours, theirs in renames.items():
        text = text.replace(f"JOINT {ours}\n", f"JOINT {theirs}\n").replace(f"ROOT {ours}\n", f"ROOT {theirs}\n")
    p = _corrupt(small_bvh, text, "renamed.bvh")
    with pytest.raises(ValueError, match=r"not found.*pass joint_map=\{our_name: their_name\}.*bone00") as err:
        import_bvh(p)
    assert "pelvis" in str(err.value)
    # the fix the message suggests works: an explicit joint_map gives the original motion back
    seq = import_bvh(p, joint_map=renames)
    np.testing.assert_allclose(seq.joints, import_bvh(small_bvh).joints, atol=1e-6)


def test_joint_map_with_unknown_names(small_bvh):
    with pytest.raises(ValueError, match=r"joint_map keys \['elbow_l'\] are not our joints.*left_elbow"):
        import_bvh(small_bvh, joint_map={"elbow_l": "left_elbow"})
    with pytest.raises(ValueError, match=r"joint_map values .*'NoSuchJoint'.*not joints of the skeleton; it has: .*left_elbow"):
        import_bvh(small_bvh, joint_map={"left_elbow": "NoSuchJoint"})
    with pytest.raises(TypeError, match="joint_map must be a dict"):
        import_bvh(small_bvh, joint_map="left_elbow")


def test_bad_arguments(small_bvh, tmp_path):
    with pytest.raises(ValueError, match="up must be 'y' or 'z'"):
        import_bvh(small_bvh, up="x")
    with pytest.raises(ValueError, match="unit_scale"):
        import_bvh(small_bvh, unit_scale=0.0)
    with pytest.raises(ValueError, match="fps must be positive"):
        import_bvh(small_bvh, fps=-1)
    R, root = _plausible(2)
    with pytest.raises(ValueError, match=r"rot must be \(T, 24, 3, 3\)"):
        write_bvh(tmp_path / "x.bvh", R[:, :22], root, rest_offsets(), 30)
    with pytest.raises(ValueError, match="fps must be positive"):
        write_bvh(tmp_path / "x.bvh", R, root, rest_offsets(), 0)
    assert not (tmp_path / "x.bvh").exists()


def test_frame_rates_and_frame_counts_outside_the_budget_are_refused_before_reading(tmp_path):
    from trumans.limits import MAX_FRAMES
    from trumans.resample import resample_times

    p = tmp_path / "slow.bvh"
    p.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
                 " End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 1e6\n0 0 0\n0 0 0\n")
    with pytest.raises(ValueError, match="between 1 and 1000 frames per second"):
        read_bvh(p)
    with pytest.raises(ValueError, match="between 1 and 1000"):
        resample_times(100, 30.0, 1e9)  # would ask for 3.3e9 frames
    with pytest.raises(ValueError, match="limit of"):
        resample_times(MAX_FRAMES, 30.0, 60.0)
    assert len(resample_times(31, 30.0, 10.0)) == 11


def test_a_utf8_byte_order_mark_is_read_past(tmp_path):
    text = ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n"
            " End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.0333333\n0 0 0\n0 1 0\n")
    p = tmp_path / "bom.bvh"
    p.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert read_bvh(p).num_frames == 2
