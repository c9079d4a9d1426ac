"""The sampling statistics' standing start pose (trumans.model.motion_stats.standing_pose)."""
import numpy as np
import pytest

from trumans.model.motion_stats import standing_pose
from trumans.skeleton import ELBOWS, REST_JOINTS, SUBTREE, WRISTS, bone_lengths, heading


def _arms_turned(angle: float, yaw: float, shift: np.ndarray) -> np.ndarray:
    """The rest pose with both forearms (elbow down) turned by ``angle`` about the elbow's x axis,
    then the whole body turned by ``yaw`` and moved by ``shift``."""
    J = REST_JOINTS.astype(np.float64).copy()
    c, s = np.cos(angle), np.sin(angle)
    Rx = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    for e, w in zip(ELBOWS, WRISTS):
        sub = SUBTREE[w]
        J[sub] = (J[sub] - J[e]) @ Rx.T + J[e]
    c, s = np.cos(yaw), np.sin(yaw)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return J @ Rz.T + shift


def test_standing_pose_is_a_real_frame_in_the_canonical_frame():
    rng = np.random.default_rng(0)
    frames = np.stack([_arms_turned(a, y, np.r_[rng.uniform(-3, 3, 2), 0.0])
                       for a, y in zip(rng.uniform(-1.2, 1.2, 41), rng.uniform(-np.pi, np.pi, 41))])
    pose = standing_pose(frames)
    # bones of one body: not shortened like the coordinate-wise median's forearms
    np.testing.assert_allclose(bone_lengths(pose), bone_lengths(REST_JOINTS), atol=1e-9)
    upright = np.stack([_arms_turned(a, 0.0, np.zeros(3)) for a in rng.uniform(-1.2, 1.2, 41)])
    median = np.median(upright, axis=0)  # what the start pose used to be
    forearm = lambda J: np.linalg.norm(J[list(WRISTS)] - J[list(ELBOWS)], axis=-1)  # noqa: E731
    assert (forearm(median) < 0.97 * forearm(REST_JOINTS)).all()
    np.testing.assert_allclose(forearm(pose), forearm(REST_JOINTS), atol=1e-9)
    # canonical: pelvis over the origin, facing +x; the chosen frame's forearms are the least turned
    np.testing.assert_allclose(pose[0, :2], 0.0, atol=1e-9)
    assert abs(heading(pose)) < 1e-9
    assert np.linalg.norm(pose - REST_JOINTS * [1, 1, 1] + REST_JOINTS[0] * [1, 1, 0], axis=-1).max() < 0.1
    with pytest.raises(ValueError, match=r"\(N, 24, 3\)"):
        standing_pose(np.zeros((0, 24, 3)))


def test_every_body_weighs_the_same_with_per_body():
    """Many frames of a small body and a few of a middle and a tall one: by frame the start pose is
    the small body; with one vote per body it is the middle one (the median body)."""
    rng = np.random.default_rng(1)

    def body(scale: float, n: int) -> np.ndarray:
        return np.stack([_arms_turned(a, y, np.r_[rng.uniform(-2, 2, 2), 0.0]) * scale
                         for a, y in zip(rng.uniform(-0.3, 0.3, n), rng.uniform(-np.pi, np.pi, n))])

    frames = np.concatenate([body(0.9, 60), body(1.0, 6), body(1.1, 6)])
    legs = lambda J: bone_lengths(J).sum()  # noqa: E731
    assert legs(standing_pose(frames)) == pytest.approx(0.9 * legs(REST_JOINTS), rel=1e-6)
    assert legs(standing_pose(frames, per_body=6)) == pytest.approx(legs(REST_JOINTS), rel=1e-6)
    with pytest.raises(ValueError, match="per_body"):
        standing_pose(frames, per_body=0)


def test_sampling_stats_leave_out_the_real_takes_unless_asked(tmp_path) -> None:
    """The real takes' labels come from the motion, in fragments; the planner's durations and walking
    speed are taken from the other takes unless ``real_takes``; with only real takes that is an error."""
    from helpers import DATASET_VOCAB, make_tiny_dataset
    from trumans.dataset import Dataset
    from trumans.model.motion_stats import sampling_stats

    root = make_tiny_dataset(tmp_path / "d", num_seqs=6)
    ds = Dataset(root)
    train = list(ds.index["splits"]["train"])
    every = sampling_stats(ds, "train", DATASET_VOCAB, 10.0)
    ds.index["real"] = {train[0]: {}}
    rest = sampling_stats(ds, "train", DATASET_VOCAB, 10.0)
    assert rest["walk_speed"] != every["walk_speed"]  # the first take no longer counts
    assert sampling_stats(ds, "train", DATASET_VOCAB, 10.0, real_takes=True) == every
    ds.index["real"] = {f: {} for f in train}
    with pytest.raises(ValueError, match="no non-real sequences"):
        sampling_stats(ds, "train", DATASET_VOCAB, 10.0)
    one = sampling_stats(ds, "train", DATASET_VOCAB, 10.0, max_sequences=1, real_takes=True)
    assert one["walk_speed"] > 0
