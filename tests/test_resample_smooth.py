"""trumans.resample.resample_smooth (raw capture keys -> a sequence rate) and the corpus's source joints."""
import numpy as np
import pytest

from trumans.importers.joint_maps import retarget_joints
from trumans.resample import resample_smooth, resample_times
from trumans.skeleton import JOINT_INDEX, PARENTS, REST_JOINTS


def test_slow_motion_passes_and_lands_on_the_output_times():
    t = np.arange(73) / 24.0  # 3 s of 24 fps keys
    keys = np.stack([np.sin(2 * np.pi * 0.8 * t), np.cos(2 * np.pi * 1.5 * t)], -1)
    out = resample_smooth(keys, 24.0, 30.0)
    assert out.shape == (len(resample_times(73, 24.0, 30.0)), 2)
    to = np.arange(len(out)) / 30.0
    want = np.stack([np.sin(2 * np.pi * 0.8 * to), np.cos(2 * np.pi * 1.5 * to)], -1)
    inner = slice(15, -15)  # away from the clip's ends
    assert np.abs(out[inner] - want[inner]).max() < 0.02


def test_key_noise_is_removed_and_no_jerk_spike_at_keys():
    rng = np.random.default_rng(0)
    t = np.arange(240) / 24.0
    clean = 0.3 * np.sin(2 * np.pi * 1.0 * t)[:, None]
    noisy = clean + rng.normal(0, 0.002, clean.shape)  # 2 mm marker noise
    out = resample_smooth(noisy, 24.0, 30.0)
    to = np.arange(len(out)) / 30.0
    err = np.abs(out[:, 0] - 0.3 * np.sin(2 * np.pi * to))[30:-30]
    assert err.std() < 0.5 * 0.002  # most of the noise is gone
    jerk = np.abs(np.diff(out[30:-30, 0], n=3)) * 30 ** 3
    true = (2 * np.pi) ** 3 * 0.3  # peak jerk of the sine, m/s^3
    assert np.percentile(jerk, 95) < 1.5 * true
    # a linear interpolation of the same keys jerks at every key
    lin = np.interp(to, t, noisy[:, 0])
    assert np.percentile(np.abs(np.diff(lin[30:-30], n=3)) * 30 ** 3, 95) > 3 * true


def test_bad_keys_are_refused():
    with pytest.raises(ValueError, match="at least 2 frames"):
        resample_smooth(np.zeros((1, 3)), 24.0, 30.0)
    with pytest.raises(ValueError, match="finite"):
        resample_smooth(np.array([[0.0], [np.nan], [1.0]]), 24.0, 30.0)
    with pytest.raises(ValueError, match="cutoff_hz"):
        resample_smooth(np.zeros((10, 3)), 24.0, 30.0, cutoff_hz=0.0)


def test_cmu_mb_neck_and_clavicles_on_spine1_get_length():
    """The cgspeed CMU BVH put Neck and the clavicles (LeftShoulder) on Spine1: retargeted, no upper-spine
    bone may have zero length."""
    R = REST_JOINTS
    names = {"Hips": R[0], "LeftUpLeg": R[1], "RightUpLeg": R[2], "Spine": R[3], "LeftLeg": R[4], "RightLeg": R[5],
             "Spine1": R[6], "LeftFoot": R[7], "RightFoot": R[8], "LeftToeBase": R[10], "RightToeBase": R[11],
             "Neck": R[6], "Neck1": R[12], "Head": R[15], "LeftShoulder": R[6], "RightShoulder": R[6],
             "LeftArm": R[16], "RightArm": R[17], "LeftForeArm": R[18], "RightForeArm": R[19], "LeftHand": R[20],
             "RightHand": R[21], "LeftHandIndex1": R[22], "RightHandIndex1": R[23]}
    P = np.broadcast_to(np.stack(list(names.values())), (3, len(names), 3)).copy()
    out = retarget_joints(list(names), P)
    bones = np.linalg.norm(out[0, 1:] - out[0, np.asarray(PARENTS[1:])], axis=-1)
    assert bones.min() > 0.01
    np.testing.assert_allclose(out[0, JOINT_INDEX["neck"]], R[JOINT_INDEX["neck"]], atol=1e-9)
    for side in ("left", "right"):  # the clavicle lies between the chest and the shoulder
        c, s = out[0, JOINT_INDEX[f"{side}_collar"]], out[0, JOINT_INDEX[f"{side}_shoulder"]]
        assert np.linalg.norm(c - out[0, JOINT_INDEX["spine3"]]) > 0.02 and np.linalg.norm(c - s) > 0.02


def test_joint_resampling_keeps_the_bone_lengths_of_a_fast_swing():
    """A leg swinging fast about the hip: a low-pass of positions alone shortens the shin and foot;
    ``resample_joints_smooth`` keeps every bone's length and the swing's slow part."""
    from trumans.resample import resample_joints_smooth

    t = np.arange(96) / 24.0
    keys = np.broadcast_to(REST_JOINTS, (len(t), 24, 3)).copy()
    hip, knee, ankle, foot = (JOINT_INDEX[f"left_{n}"] for n in ("hip", "knee", "ankle", "foot"))
    angle = 0.6 * np.sin(2 * np.pi * 4.0 * t)  # 4 Hz swing about the hip's x axis, partly above the cutoff
    c, s = np.cos(angle), np.sin(angle)
    for j in (knee, ankle, foot):
        v = REST_JOINTS[j] - REST_JOINTS[hip]
        keys[:, j] = REST_JOINTS[hip] + np.stack([np.full_like(c, v[0]), c * v[1] - s * v[2], s * v[1] + c * v[2]], -1)
    rest = np.linalg.norm(REST_JOINTS[1:] - REST_JOINTS[np.asarray(PARENTS[1:])], axis=-1)
    out = resample_joints_smooth(keys, 24.0, 30.0)
    bones = np.linalg.norm(out[:, 1:] - out[:, np.asarray(PARENTS[1:])], axis=-1)
    np.testing.assert_allclose(bones, np.broadcast_to(rest, bones.shape), atol=1e-9)
    plain = resample_smooth(keys, 24.0, 30.0)
    shin = np.linalg.norm(plain[:, ankle] - plain[:, knee], axis=-1)
    assert rest[ankle - 1] - shin.min() > 0.002  # what the plain low-pass would have done
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        resample_joints_smooth(np.zeros((10, 23, 3)), 24.0, 30.0)
