"""HOI filter data side: frame vector round trips, canonical frames, IMU simulation, corruption,
regularisers on analytic cases, windows and overlap blending."""
from dataclasses import replace

import numpy as np
import pytest
import torch

from trumans.refine import (COND_DIM, FRAME_DIM, CorruptionConfig, add_clean_imu, blend_windows, condition_features,
                         corrupt, frames_from_sequence, from_frame, pack_frames, resample_frames,
                         sequence_from_frames, simulate_imu_acc, to_frame, unpack_frames, window_frame,
                         window_starts, window_weights)
from trumans.refine.frame import IMU_A, IMU_FLAG, IMU_R, JOINTS, OBJ_R, OBJ_T, ROTATIONS
from trumans.refine.losses import loss_consist, loss_imu, loss_off, loss_pose, loss_vel
from trumans.rotations import sixd_to_matrix
from trumans.sequence import load_sequence, save_sequence
from trumans.skeleton import rest_offsets

from helpers import carried_box_clip


def test_frame_vector_round_trip(tmp_path):
    s = carried_box_clip()
    f, name = frames_from_sequence(s)
    assert name == "box_0" and f.shape == (40, FRAME_DIM) and (f[:, IMU_FLAG] == 1).all()
    back = sequence_from_frames(f, s.fps, name, "box", template=s)
    np.testing.assert_allclose(back.joints, s.joints, atol=1e-6)
    np.testing.assert_allclose(back.rotations, s.rotations, atol=1e-5)
    np.testing.assert_allclose(back.objects["box_0"].pose, s.objects["box_0"].pose, atol=1e-5)
    np.testing.assert_allclose(back.objects["box_0"].imu_acc, s.objects["box_0"].imu_acc, atol=1e-4)
    assert "lamp" in back.objects and back.objects["box_0"].category == "box"
    f2, _ = frames_from_sequence(back, "box_0")
    np.testing.assert_allclose(f2, f, atol=1e-5)
    # no IMU: zeros plus flag 0, and the rebuilt sequence has no IMU
    s.objects["box_0"].imu_rot = s.objects["box_0"].imu_acc = None
    f3, _ = frames_from_sequence(s, "box_0")
    assert (f3[:, IMU_FLAG] == 0).all() and (f3[:, IMU_R] == 0).all() and (f3[:, IMU_A] == 0).all()
    assert sequence_from_frames(f3, 30.0, "box_0", "box").objects["box_0"].imu_rot is None
    # NaN frames survive a file round trip as missing
    s.joints[5] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        s.validate()
    s.allow_missing = True
    save_sequence(s, tmp_path / "t.npz")
    t = load_sequence(tmp_path / "t.npz", allow_missing=True)
    f4, _ = frames_from_sequence(t, "box_0")
    assert np.isnan(f4[5, JOINTS]).all() and np.isfinite(f4[4]).all()
    with pytest.raises(ValueError, match="NaN"):
        load_sequence(tmp_path / "t.npz")


def test_frame_errors():
    s = carried_box_clip()
    with pytest.raises(ValueError, match="'cup' is not in the sequence"):
        frames_from_sequence(s, "cup")
    with pytest.raises(ValueError, match=r"\(T, 235\)"):
        unpack_frames(np.zeros((4, 200)))
    with pytest.raises(ValueError, match=r"\(T, 24, 3\)"):
        pack_frames(np.zeros((4, 22, 3)), None, np.tile(np.eye(4), (4, 1, 1)))
    with pytest.raises(ValueError, match="both imu_rot"):
        pack_frames(np.zeros((4, 24, 3)), None, np.tile(np.eye(4), (4, 1, 1)), imu_rot=np.zeros((4, 6)))
    s.objects = {}
    with pytest.raises(ValueError, match="no object track"):
        frames_from_sequence(s)


def test_condition_and_canonical_frame():
    s = carried_box_clip()
    f, _ = frames_from_sequence(s)
    f[3, JOINTS][:3] = np.nan  # pelvis missing on frame 3
    f[7, OBJ_T] = np.nan
    c = condition_features(f)
    assert c.shape == (40, COND_DIM) and np.isfinite(c).all()
    assert c[3, FRAME_DIM] == 0 and c[3, FRAME_DIM + 1] == 1 and c[7, -1] == 0 and c[6, -1] == 1
    np.testing.assert_allclose(c[3, :3], (f[2, :3] + f[4, :3]) / 2, atol=1e-6)  # gaps: linear in time
    np.testing.assert_allclose(c[7, OBJ_T], (f[6, OBJ_T] + f[8, OBJ_T]) / 2, atol=1e-6)
    g = f.copy()
    g[:5, ROTATIONS] = np.nan  # leading gap: held at the first observation; a never-observed column: 0
    g[:, IMU_A] = np.nan
    c = condition_features(g)
    np.testing.assert_allclose(c[:5, ROTATIONS], np.repeat(g[5:6, ROTATIONS], 5, 0))
    assert (c[:, IMU_A] == 0).all() and c[0, FRAME_DIM + 24] == 0 and c[5, FRAME_DIM + 24] == 1
    o, y = window_frame(f)
    np.testing.assert_allclose(o[:2], np.nanmean(f[:, 0:2], 0), atol=1e-5)
    # canonical <-> world is exact, and moves the object and IMU with the body
    rng = np.random.default_rng(0)
    W = add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(seed=k))[0] for k in range(3)]), 30.0)
    o, y = rng.normal(size=(3, 3)), rng.uniform(-3, 3, 3)
    C = to_frame(W, o, y)
    np.testing.assert_allclose(from_frame(C, o, y), W, atol=2e-5)
    d_world = np.linalg.norm(W[..., OBJ_T] - W[..., 63:66], axis=-1)  # object to right wrist
    d_can = np.linalg.norm(C[..., OBJ_T] - C[..., 63:66], axis=-1)
    np.testing.assert_allclose(d_can, d_world, atol=1e-5)
    np.testing.assert_allclose(C[..., IMU_R], C[..., OBJ_R], atol=1e-5)  # IMU turns with the object


def test_simulated_imu_and_resampling():
    t = np.arange(60) / 30.0
    traj = np.stack([0.5 * 2.0 * t ** 2, np.zeros(60), 3 * t], -1)  # constant acceleration 2 m/s² in x
    a = simulate_imu_acc(traj, 30.0)
    np.testing.assert_allclose(a[4:-4], np.tile([2.0, 0, 0], (52, 1)), atol=1e-9)
    f, _ = frames_from_sequence(carried_box_clip())
    up = resample_frames(f, 30.0, 60.0)
    assert up.shape == (79, FRAME_DIM)
    np.testing.assert_allclose(up[::2], f, atol=1e-5)  # the source frames come back exactly
    np.testing.assert_allclose(resample_frames(up, 60.0, 30.0), f, atol=1e-5)


def test_corruption_is_seeded_and_shaped():
    W = add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(T=64, seed=k))[0] for k in range(8)]), 30.0)
    a = corrupt(W, 30.0, np.random.default_rng(3))
    b = corrupt(W, 30.0, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    assert a.shape == W.shape and not np.isinf(a).any()
    err = np.nanmean(np.linalg.norm((a - W)[..., JOINTS].reshape(8, 64, 24, 3), axis=-1))
    assert 0.01 < err < 0.1
    # no IMU: zeros and flag 0; drift preset: no missing values, always an IMU
    n = corrupt(W, 30.0, np.random.default_rng(0), CorruptionConfig().without_imu())
    assert (n[..., IMU_FLAG] == 0).all() and (n[..., IMU_R] == 0).all()
    d = corrupt(W, 30.0, np.random.default_rng(0), CorruptionConfig.drift())
    assert np.isfinite(d).all() and (d[..., IMU_FLAG] == 1).all()
    with pytest.raises(ValueError, match="probability"):
        CorruptionConfig(p_flip=2.0)
    with pytest.raises(ValueError, match=r"\(B, L, 235\)"):
        corrupt(W[0], 30.0, np.random.default_rng(0))


def test_corruption_position_scale_sets_each_window_s_severity():
    W = add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(T=64, seed=k))[0] for k in range(16)]), 30.0)
    off = CorruptionConfig(p_joint_occlusion=0.0, p_dropout=0.0, p_freeze=0.0)

    def per_window(cfg):
        e = np.linalg.norm((corrupt(W, 30.0, np.random.default_rng(0), cfg) - W)[..., JOINTS].reshape(16, 64, 24, 3), axis=-1)
        return e.mean(axis=(1, 2))

    base = per_window(off)
    assert np.array_equal(per_window(replace(off, position_scale=(1.0, 1.0))), base)  # the default draws nothing
    np.testing.assert_allclose(per_window(replace(off, position_scale=(0.0, 0.0))), 0.0, atol=1e-6)
    mixed = per_window(replace(off, position_scale=(0.0, 2.0)))
    assert mixed.min() < 0.5 * base.mean() and mixed.max() > 1.3 * base.mean()  # windows differ in severity
    with pytest.raises(ValueError, match="position_scale"):
        CorruptionConfig(position_scale=(1.0, 0.5))


def _t(x):
    return torch.as_tensor(np.asarray(x, np.float64))


def test_regularisers_analytic():
    W = add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(T=32, seed=k))[0] for k in range(2)]), 30.0).astype(np.float64)
    x = _t(W)
    off = _t(np.stack([rest_offsets()] * 2))
    # exact prediction: every term vanishes (L_imu too: a constant-acceleration object with its
    # exact IMU and the kinematically consistent eq. 13)
    assert loss_off(x, x) < 1e-9 and loss_vel(x, x) < 1e-9 and loss_consist(x, off) < 1e-5
    q = x.clone()
    tt = torch.arange(32, dtype=torch.float64)[None, :, None] / 30.0
    q[..., OBJ_T] = 0.5 * torch.tensor([2.0, -1.0, 0.5], dtype=torch.float64) * tt ** 2 + 0.3 * tt
    q[..., IMU_A] = _t(simulate_imu_acc(q[..., OBJ_T].numpy(), 30.0))
    np.testing.assert_allclose(q[:, 4:-4, IMU_A].numpy(), np.tile([2.0, -1.0, 0.5], (2, 24, 1)), atol=1e-9)
    q[:, :4, IMU_FLAG] = q[:, -4:, IMU_FLAG] = 0  # eq. 16's clamped ends are not exact
    assert loss_imu(q, q, q, 30.0) < 1e-9
    # a global shift of everything: L_off and L_vel are 0 (relative / velocity terms), L_consist too
    shift = x.clone()
    shift[..., JOINTS] += 0.1
    shift[..., OBJ_T] += 0.1
    assert loss_off(shift, x) < 1e-9 and loss_vel(shift, x) < 1e-9 and loss_consist(shift, off) < 1e-5
    # moving only the object by d: L_off = 24 joints * |d|_1
    obj = x.clone()
    obj[..., OBJ_T] += torch.tensor([0.01, -0.02, 0.0], dtype=torch.float64)
    assert abs(loss_off(obj, x).item() - 24 * 0.03) < 1e-9
    # a step in the object at frame 10: L_vel sees one displaced difference per clip: 0.03 / 31
    step = x.clone()
    step[:, 10:, OBJ_T] += torch.tensor([0.01, -0.02, 0.0], dtype=torch.float64)
    assert abs(loss_vel(step, x).item() - 0.03 / 31) < 1e-9
    # moving one joint by 5 cm in z: L_consist = 0.05 (its own error; FK places it at its true spot)
    j = x.clone()
    j[..., 3 * 15 + 2] += 0.05  # head z
    assert abs(loss_consist(j, off).item() - 0.05) < 1e-5
    # the pose term: a body shift costs nothing; one joint 5 cm off costs 0.05; the pelvis 5 cm off
    # moves every other joint's offset from it: 23 x 0.05
    assert loss_pose(shift, x) < 1e-9 and abs(loss_pose(j, x).item() - 0.05) < 1e-9
    pel = x.clone()
    pel[..., 2] += 0.05
    assert abs(loss_pose(pel, x).item() - 23 * 0.05) < 1e-9
    # L_rot: object rotation vs IMU rotation, only where the IMU flag is set
    tr = q.clone()
    tr[..., IMU_R] += 0.1
    assert abs(loss_imu(q, q, tr, 30.0).item() - 0.6) < 1e-9
    tr[..., IMU_FLAG] = 0
    assert loss_imu(q, q, tr, 30.0).item() == 0
    # L_acc: a constant object velocity predicted but the IMU says a = 1 m/s² in x: τ² per step
    v = x.clone()
    v[..., OBJ_T] = torch.arange(32, dtype=torch.float64)[None, :, None] * 0.01
    tr = v.clone()
    tr[..., IMU_R] = tr[..., OBJ_R]
    tr[..., IMU_A] = torch.tensor([1.0, 0, 0], dtype=torch.float64)
    assert abs(loss_imu(v, v, tr, 30.0).item() - (1 / 30) ** 2) < 1e-9


def test_windows_and_blending():
    assert window_starts(10, 64, 16).tolist() == [0]
    assert window_starts(64, 64, 16).tolist() == [0]
    st = window_starts(200, 64, 16)
    assert st.tolist() == [0, 48, 96, 136] and st[-1] + 64 == 200
    with pytest.raises(ValueError, match="overlap"):
        window_starts(100, 64, 64)
    w = window_weights(st, 64)
    assert w.min() > 0 and w[0, :48].min() == 1 and w[-1, -1] == 1
    # a long signal cut into windows is blended back exactly (pieces agree where they overlap)
    rng = np.random.default_rng(0)
    sig = rng.normal(size=(200, 5))
    pieces = np.stack([sig[s:s + 64] for s in st])
    np.testing.assert_allclose(blend_windows(pieces, st, 200), sig, atol=1e-12)
    # where they disagree, the blend stays between them and is continuous across an overlap
    pieces2 = pieces.copy()
    pieces2[1] += 1.0
    out = blend_windows(pieces2, st, 200)
    assert np.all(out[48:64] - sig[48:64] >= -1e-12) and np.all(out[48:64] - sig[48:64] <= 1 + 1e-12)
    assert np.abs(np.diff(out[40:70, 0] - sig[40:70, 0])).max() < 0.07
    # a short sequence: one window, the padded tail dropped
    np.testing.assert_allclose(blend_windows(np.concatenate([sig[:10], np.zeros((54, 5))])[None], [0], 10), sig[:10])
    with pytest.raises(ValueError, match="do not cover"):
        blend_windows(pieces[:2], st[:2], 200)


def test_corruption_reports_the_body_drift_it_added():
    W = add_clean_imu(np.stack([frames_from_sequence(carried_box_clip(T=64, seed=k))[0] for k in range(4)]), 30.0)
    # only the drifts left: no jitter, spikes, freezes or missing joints
    cfg = CorruptionConfig(jitter_m=0.0, p_spike=0.0, joint_drift_m=0.0, p_joint_occlusion=0.0, p_dropout=0.0,
                           p_freeze=0.0, position_scale=(0.5, 2.0))
    parts: dict = {}
    a = corrupt(W, 30.0, np.random.default_rng(5), cfg, parts=parts)
    np.testing.assert_array_equal(a, corrupt(W, 30.0, np.random.default_rng(5), cfg))  # asking changes nothing
    d = parts["body_drift"]
    assert d.shape == (4, 64, 3) and np.abs(d).max() > 0.005
    moved = (a - W)[..., JOINTS].reshape(4, 64, 24, 3)
    np.testing.assert_allclose(moved, np.broadcast_to(d[:, :, None], moved.shape), atol=1e-6)  # every joint, alike
