"""Shared non-fixture test helpers: paths, tiny models and datasets, toy scenes and bodies.

pytest puts tests/ (the folder of the rootdir conftest.py) on sys.path, so a test module in any
subfolder imports these with ``from helpers import ...``. Fixtures live in tests/conftest.py."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from trumans.actions import ActionInterval, labels_from_intervals
from trumans.dataset import content_hash, write_index
from trumans.model.checkpoint import Checkpoint
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import FeatureLayout, Normalizer
from trumans.model.nets import ActionEncoderConfig, Denoiser, DenoiserConfig, ScenePerceiverConfig
from trumans.refine import simulate_imu_acc
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d
from trumans.scenes.occupancy import OccupancyGrid
from trumans.sequence import ObjectTrack, Sequence, save_sequence
from trumans.skeleton import REST_JOINTS, forward_kinematics, rest_offsets

TESTS_DIR = Path(__file__).resolve().parent
REPO_ROOT = TESTS_DIR.parent
TEST_DATA = TESTS_DIR / "data"  # the small committed inputs (tests/data/README.md says where each comes from)
CMU_WALK_BVH = TEST_DATA / "cmu_131_01_start_walk_stop_first480.bvh"

# ---- sampling: a tiny untrained generator ---------------------------------------------------------------------

SAMPLE_VOCAB = ["stand", "walk", "sit_down", "sit", "stand_up", "drink"]


def tiny_checkpoint(seed: int = 0) -> Checkpoint:
    """An untrained 16-frame generator checkpoint over SAMPLE_VOCAB (fast enough for rollout tests)."""
    torch.manual_seed(seed)
    cfg = DenoiserConfig(layout=FeatureLayout(), frames=16, d_model=32, layers=1, heads=2, ff=32, dropout=0.0,
                         scene=ScenePerceiverConfig(grid=16, patch=8, d_model=16, layers=1, heads=2, ff=16, dropout=0.0),
                         action=ActionEncoderConfig(num_actions=len(SAMPLE_VOCAB), frames=16, d_model=16, layers=1,
                                                    heads=2, ff=16, dropout=0.0))
    model = Denoiser(cfg)
    rest = REST_JOINTS.copy()
    mean = np.tile(rest.reshape(-1), 1).astype(np.float32)
    return Checkpoint(kind="generator", model_config=cfg, diffusion_config=DiffusionConfig(steps=20, schedule="cosine",
                                                                                          prediction="x0"),
                      model_state=model.state_dict(), normalizer=Normalizer(mean, np.full(72, 0.3, np.float32)),
                      vocabulary=SAMPLE_VOCAB, fps=10.0, L_epi=16, k=2, grid={"n": 16, "extent": [1.2, 1.2, 1.2]},
                      meta={"walk_speed": 1.0})


def box_room() -> OccupancyGrid:
    """Floor (z < 0) plus a box x in [1.0, 1.4], y in [0.6, 1.4], z in [0, 1.0] at 2 cm voxels."""
    origin = np.array([0.01, 0.01, -0.09])
    c = origin[:, None] + 0.02 * np.arange(120)[None]  # (3, 120) voxel centres per axis
    x, y, z = np.meshgrid(*c, indexing="ij")
    grid = (z < 0) | ((x > 1.0) & (x < 1.4) & (y > 0.6) & (y < 1.4) & (z < 1.0))
    return OccupancyGrid(grid, origin, 0.02)


def standing_body(T: int) -> np.ndarray:
    """(1, T, 24, 3) rest pose with the feet on the floor (lowest foot joint at its rest height)."""
    from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT

    rot = np.broadcast_to(np.eye(3), (T, 24, 3, 3)).copy()
    P, _ = forward_kinematics(rot, np.zeros((T, 3)), rest_offsets())
    low = (P[0, list(FOOT_JOINTS), 2] - FOOT_REST_HEIGHT).min()
    P[..., 2] -= low
    return P[None]


# ---- training: a tiny generator dataset and config ------------------------------------------------------------

DATASET_VOCAB = ["walk", "sit", "reach"]

TINY_TOML = """
name = "tiny"
[model]
d_model = 32
layers = 2
heads = 4
ff = 64
dropout = 0.1
[scene]
d_model = 16
layers = 1
heads = 2
ff = 32
[action]
d_model = 16
layers = 1
heads = 2
ff = 32
[data]
stride = 3
max_val_episodes = 64
[train]
steps = 6
batch_size = 8
lr = 1e-3
warmup_steps = 2
checkpoint_every = 3
val_every = 3
val_batch_size = 32
"""


def make_tiny_dataset(root: Path, num_seqs: int = 6, frames: int = 150, seed: int = 0) -> Path:
    """A dataset folder: random-walk-ish 30 fps motions from FK, a 3 m room with a box, index.json."""
    rng = np.random.default_rng(seed)
    root = Path(root)
    scene_dir = root / "scenes" / "room0"
    scene_dir.mkdir(parents=True, exist_ok=True)
    grid = np.zeros((60, 60, 44), dtype=bool)
    grid[40:50, 10:30, :10] = True  # a 0.5 x 1.0 x 0.5 m box
    OccupancyGrid(grid, np.array([-1.5 + 0.025, -1.5 + 0.025, 0.025]), 0.05).save(scene_dir / "occupancy.npz")
    paths = []
    for s in range(num_seqs):
        t = np.arange(frames) / 30.0
        yaw = rng.uniform(-np.pi, np.pi) + 0.3 * np.sin(t * rng.uniform(0.5, 1.5))
        speed = rng.uniform(0.3, 1.0)
        root_xy = np.cumsum(np.stack([np.cos(yaw), np.sin(yaw)], -1) * speed / 30.0, 0) + rng.uniform(-0.5, 0.5, 2)
        aa = np.zeros((frames, 24, 3))
        aa[:, 0, 2] = yaw
        phase = rng.uniform(0, 2 * np.pi, 24)
        aa[:, 1:, 0] = 0.3 * np.sin(2 * np.pi * 1.2 * t[:, None] + phase[None, 1:])
        aa[:, 1:, 1] = 0.15 * np.cos(2 * np.pi * 0.7 * t[:, None] + phase[None, 1:])
        R = axis_angle_to_matrix(aa)
        root_pos = np.concatenate([root_xy, np.full((frames, 1), 0.93)], -1)
        joints, _ = forward_kinematics(R, root_pos)
        cut = int(rng.integers(frames // 3, 2 * frames // 3))
        acts = labels_from_intervals([ActionInterval("walk", 0, cut + 1), ActionInterval("reach", cut - 10, frames)],
                                     DATASET_VOCAB, frames)
        rel = f"sequences/seq{s}.npz"
        save_sequence(Sequence(joints=joints, fps=30.0, actions=acts, action_names=DATASET_VOCAB, scene="room0"),
                      root / rel)
        paths.append(rel)
    n_val = max(1, num_seqs // 3)
    splits = {"train": paths[:-n_val], "val": paths[-n_val:], "test": []}
    write_index(root, {"name": "tiny", "version": "1", "fps": 30, "vocabulary": DATASET_VOCAB, "splits": splits,
                       "scenes": {"room0": "scenes/room0"}, "hash": content_hash(root, paths)})
    return root


def tiny_contact_dataset(root: Path) -> Path:
    """Two toy clips (one train, one val) with rule contacts, in the dataset layout."""
    from trumans.contacts.rule import ContactScene, joint_contacts
    from trumans.scenes.io import save_scene
    from trumans.synth.cases import make_case

    root = Path(root)
    splits, scenes, files = {"train": [], "val": [], "test": []}, {}, []
    for split, kind, seed in (("train", "hand", 0), ("val", "two_hands", 1)):
        seq, scene = make_case(kind, seed)
        seq.contacts = joint_contacts(seq.joints, ContactScene(scene)).contact
        scene.name = seq.scene = f"{kind}_{seed}"
        save_scene(scene, root / "scenes" / scene.name)
        rel = f"sequences/{scene.name}.npz"
        save_sequence(seq, root / rel)
        splits[split].append(rel)
        scenes[scene.name] = f"scenes/{scene.name}"
        files.append(rel)
    write_index(root, {"name": "tiny", "version": "1", "fps": 30.0, "vocabulary": [], "splits": splits,
                       "scenes": scenes, "hash": content_hash(root, files)})
    return root


# ---- refinement: a kinematically exact clip carrying an object ------------------------------------------------

def carried_box_clip(T: int = 40, seed: int = 0, imu: bool = True) -> Sequence:
    """A kinematically exact clip: random smooth rotations, FK joints, an object carried by the right wrist."""
    rng = np.random.default_rng(seed)
    aa = 0.3 * np.sin(np.linspace(0, 3, T)[:, None, None] + rng.uniform(0, 6, (1, 24, 3)))
    R = axis_angle_to_matrix(aa)
    root = np.stack([np.linspace(0, 1, T), np.zeros(T), np.full(T, 0.95)], -1)
    joints, _ = forward_kinematics(R, root)
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3] = axis_angle_to_matrix(np.stack([np.zeros(T), np.zeros(T), np.linspace(0, 2, T)], -1))
    pose[:, :3, 3] = joints[:, 21] + pose[:, :3, :3] @ [0.05, 0, 0]  # held by the right wrist, 5 cm off in its own frame
    ob = ObjectTrack(pose=pose.astype(np.float32), category="box")
    if imu:
        ob.imu_rot = matrix_to_6d(pose[:, :3, :3]).astype(np.float32)
        ob.imu_acc = simulate_imu_acc(pose[:, :3, 3], 30.0).astype(np.float32)
    return Sequence(joints=joints, fps=30.0, rotations=matrix_to_6d(R).astype(np.float32), root_pos=root,
                    objects={"box_0": ob, "lamp": ObjectTrack(pose=np.tile(np.eye(4), (T, 1, 1)), category="lamp")})


def seated(seconds: float = 8.0, fps: float = 30.0) -> np.ndarray:
    """(T, 24, 3): a body sitting on a 0.45 m seat: thighs horizontal, shins vertical, trunk upright."""
    from trumans.skeleton import JOINT_INDEX as J

    j = REST_JOINTS.copy()
    hip_z, knee_z = j[J["left_hip"], 2], j[J["left_knee"], 2]
    thigh = hip_z - knee_z
    drop = hip_z - 0.5
    up = [J[n] for n in ("pelvis", "left_hip", "right_hip", "spine1", "spine2", "spine3", "neck", "head", "left_collar",
                         "right_collar", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
                         "right_wrist", "left_index1", "right_index1")]
    j[up, 2] -= drop
    for side in ("left", "right"):
        for n in ("knee", "ankle", "foot"):
            j[J[f"{side}_{n}"], 0] += thigh
        j[J[f"{side}_knee"], 2] = j[J[f"{side}_hip"], 2]
    return np.repeat(j[None], int(seconds * fps), 0)


def sit_stand_take(fps: float = 30.0) -> np.ndarray:
    """(T, 24, 3) z-up m: 1.5 s standing (the rest pose), a 0.8-s cosine blend into ``seated``'s pose
    (from frame round(1.5 fps)), 3 s seated, a 0.8-s blend back, 1.5 s standing."""
    stand, sit = REST_JOINTS[None], seated(1.0)[:1]
    n, still = int(0.8 * fps), int(round(1.5 * fps))
    w = (0.5 - 0.5 * np.cos(np.linspace(0, np.pi, n)))[:, None, None]
    return np.concatenate([np.repeat(stand, still, 0), stand + w * (sit - stand), np.repeat(sit, 2 * still, 0),
                           sit + w * (stand - sit), np.repeat(stand, still, 0)]).astype(np.float32)
