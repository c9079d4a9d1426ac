"""Contact predictor (iReplica §4.2): attention over frames, batch independence, mirroring, checkpoints."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.model.checkpoint import resign_checkpoint

from trumans.track.model_io import load_predictor, save_predictor
from trumans.track.predictor import (MIRROR_JOINTS, ContactPredictor, ContactPredictorConfig, mirror_rotations,
                                        pose_windows, predict_contacts, window_indices)
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d, sixd_to_matrix
from trumans.skeleton import JOINT_NAMES, forward_kinematics

TINY = ContactPredictorConfig(window=9, d_model=16, hidden=16, heads=2, layers=2, ff=16, dropout=0.0)


def _rotations(T: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    aa = rng.normal(0, 0.4, (T, 24, 3))
    aa[:, 0, 2] += np.linspace(0, 3.0, T)  # the root turns
    return matrix_to_6d(axis_angle_to_matrix(aa)).astype(np.float32)


def _model(seed: int = 0, cfg: ContactPredictorConfig = TINY) -> ContactPredictor:
    torch.manual_seed(seed)
    return ContactPredictor(cfg).eval()


def test_prediction_does_not_depend_on_batch_composition():
    model = _model()
    rot = _rotations(40)
    full, cls = predict_contacts(model, rot, batch_size=64)
    for bs in (1, 7):
        p, c = predict_contacts(model, rot, batch_size=bs)
        assert np.allclose(p, full, atol=1e-5) and np.allclose(c, cls, atol=1e-5)
    # a window alone and the same window among other sequences' windows give the same output
    win = pose_windows(torch.from_numpy(rot), window_indices(np.arange(40), 0, 39, TINY.window))
    other = pose_windows(torch.from_numpy(_rotations(40, seed=3)), window_indices(np.arange(40), 0, 39, TINY.window))
    with torch.no_grad():
        alone = model(win[5:6])[0]
        mixed = model(torch.cat([other[:3], win[5:6], other[3:20]]))[0][3:4]
    assert torch.allclose(alone, mixed, atol=1e-5)
    assert full.shape == (40, 2) and ((full > 0) & (full < 1)).all()
    assert cls.shape == (40, 4) and np.allclose(cls.sum(1), 1.0, atol=1e-5)


def test_strided_prediction_matches_centre_frames():
    model = _model(4)
    rot = _rotations(23)
    full, _ = predict_contacts(model, rot)
    p3, c3 = predict_contacts(model, rot, stride=3, batch_size=4)
    assert p3.shape == (23, 2) and c3.shape == (23, 4)
    centres = np.arange(1, 22, 3)  # frames that are the centre of their window
    assert np.allclose(p3[centres], full[centres], atol=1e-5)
    assert np.abs(p3 - full).max() > 0  # the other frames come from an off-centre position
    with pytest.raises(ValueError, match="stride"):
        predict_contacts(model, rot, stride=2)


def test_attention_runs_over_the_frames_of_a_window():
    model = _model(1)
    win = pose_windows(torch.from_numpy(_rotations(30)), window_indices(np.array([15]), 0, 29, TINY.window))
    changed = win.clone()
    changed[0, 0, 18] = -changed[0, 0, 18]  # the left wrist in the window's FIRST frame only
    with torch.no_grad():
        a, b = model(win)[0][0, TINY.window // 2], model(changed)[0][0, TINY.window // 2]
    assert not torch.allclose(a, b)  # the centre frame sees the other frames


def test_windows_are_heading_invariant():
    rot = _rotations(20)
    R = sixd_to_matrix(rot.astype(np.float64))
    yaw = axis_angle_to_matrix(np.array([0.0, 0.0, 1.1]))
    turned = R.copy()
    turned[:, 0] = yaw @ R[:, 0]
    idx = window_indices(np.arange(20), 0, 19, TINY.window)
    a = pose_windows(torch.from_numpy(rot), idx)
    b = pose_windows(torch.from_numpy(matrix_to_6d(turned).astype(np.float32)), idx)
    assert torch.allclose(a, b, atol=1e-5)
    assert idx[0].tolist() == [0, 0, 0, 0, 0, 1, 2, 3, 4] and idx[-1, -1] == 19


def test_mirror_is_a_reflection_of_the_skeleton():
    rot = _rotations(6)
    root = np.tile([0.3, 0.2, 0.9], (6, 1))
    J, _ = forward_kinematics(sixd_to_matrix(rot.astype(np.float64)), root)
    Jm, _ = forward_kinematics(sixd_to_matrix(mirror_rotations(rot).astype(np.float64)), root * [1, -1, 1])
    reflect = np.array([1.0, -1.0, 1.0])
    assert np.allclose(Jm, J[:, MIRROR_JOINTS] * reflect, atol=1e-5)
    assert np.allclose(mirror_rotations(mirror_rotations(rot)), rot)
    assert JOINT_NAMES[MIRROR_JOINTS[JOINT_NAMES.index("left_wrist")]] == "right_wrist"
    assert torch.allclose(mirror_rotations(torch.from_numpy(rot)), torch.from_numpy(mirror_rotations(rot)))


def test_config_and_input_errors():
    with pytest.raises(ValueError, match="odd"):
        ContactPredictorConfig(window=60)
    with pytest.raises(ValueError, match="unknown"):
        ContactPredictorConfig.from_dict({"window": 61, "widht": 3})
    with pytest.raises(ValueError, match="divisible"):
        ContactPredictorConfig(d_model=30, heads=4)
    model = _model()
    with pytest.raises(ValueError, match=r"\(T, 24, 6\)"):
        predict_contacts(model, np.zeros((10, 24, 3), np.float32))
    with pytest.raises(ValueError, match="windows"):
        model(torch.zeros(2, 5, 24, 6))


def test_checkpoint_round_trip(tmp_path):
    model = _model(2)
    path = tmp_path / "c.pt"
    save_predictor(model, path, data={"name": "x", "hash": "h"}, meta={"note": 1})
    loaded, info = load_predictor(path)
    rot = _rotations(12)
    assert np.allclose(predict_contacts(model, rot)[0], predict_contacts(loaded, rot)[0])
    assert info["kind"] == "contact" and info["model_config"]["window"] == TINY.window
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_predictor(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a readable"):
        load_predictor(bad)
    torch.save({"format": "trumans-checkpoint", "format_version": 1, "kind": "generator"}, tmp_path / "gen.pt")
    resign_checkpoint(tmp_path / "gen.pt")  # a signed file of another kind
    with pytest.raises(ValueError, match="'contact' checkpoint is needed"):
        load_predictor(tmp_path / "gen.pt")
    state = torch.load(path, weights_only=True)
    state["model"]["contact_head.bias"] += 1.0  # altered bytes no longer match the digest
    torch.save(state, tmp_path / "altered.pt")
    with pytest.raises(ValueError, match="digest"):
        load_predictor(tmp_path / "altered.pt")
