"""Per-hand contact prediction from body pose (iReplica §4.2, Fig. 5).

A window of ``window`` = 61 frames (30 fps, about 2 s) of local joint rotations around each frame
is embedded frame by frame with an MLP, given a learned positional encoding of the frame's place
in the window, and processed by a small transformer encoder that attends OVER THE FRAMES of each
window (``batch_first=True``: the window's frames are the sequence axis, windows never see each
other; the authors' public code attends across the batch). It outputs, per frame of the window,
the left and right hand's contact logits and the logits of the interaction class
``CLASSES`` (the dof class of the object being moved: none | slide | hinge | free, supp. §10.1).
At inference only the centre frame's prediction is kept (sliding window).

Input convention (owned here): rotations ``(T, 24, 6)`` local 6D (first two columns, root first);
the root's yaw is removed per window (the window is expressed in the centre frame's heading, as
its absolute heading carries no contact information), its pitch/roll kept.

Mirror augmentation (owned here): the skeleton's rest pose is symmetric about the sagittal plane
y = 0 of the body frame (facing +x, left +y). Mirroring maps each local rotation R of joint j to
``M R M`` (M = diag(1, -1, 1)) placed at joint mirror(j) (left <-> right), and swaps the hands'
labels. In 6D (columns c1, c2): ``c1 -> M c1``, ``c2 -> -M c2`` (since ``M e2 = -e2``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np
import torch
from einops import rearrange
from torch import nn

from trumans.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

__all__ = [
    "CLASSES",
    "HANDS",
    "HAND_JOINTS",
    "ContactPredictorConfig",
    "ContactPredictor",
    "MIRROR_JOINTS",
    "mirror_rotations",
    "window_indices",
    "pose_windows",
    "predict_contacts",
]

CLASSES: tuple[str, ...] = ("none", "slide", "hinge", "free")  # interaction class = object dof
HANDS: tuple[str, ...] = ("left", "right")
# The joints whose contact makes a hand in contact (wrist = palm, index1 = fingers).
HAND_JOINTS: dict[str, tuple[int, int]] = {
    "left": (JOINT_INDEX["left_wrist"], JOINT_INDEX["left_index1"]),
    "right": (JOINT_INDEX["right_wrist"], JOINT_INDEX["right_index1"]),
}


def _mirror_joints() -> np.ndarray:
    out = np.arange(NUM_JOINTS)
    for i, n in enumerate(JOINT_NAMES):
        if n.startswith("left_"):
            out[i] = JOINT_INDEX["right_" + n[5:]]
        elif n.startswith("right_"):
            out[i] = JOINT_INDEX["left_" + n[6:]]
    return out


MIRROR_JOINTS: np.ndarray = _mirror_joints()  # (24,) joint index of each joint's mirror image
_SIGN_6D = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0], dtype=np.float32)  # [M c1, -M c2]


@dataclass(frozen=True)
class ContactPredictorConfig:
    """window: frames per window (odd; the centre is predicted); d_model: token width; hidden:
    embedding MLP width; heads, layers, ff: transformer encoder; dropout; fps: frame rate the
    model expects (Hz)."""

    window: int = 61
    d_model: int = 32
    hidden: int = 64
    heads: int = 4
    layers: int = 2
    ff: int = 64
    dropout: float = 0.1
    fps: float = 30.0

    def __post_init__(self) -> None:
        if self.window < 1 or self.window % 2 == 0:
            raise ValueError(f"window must be a positive odd number of frames, got {self.window}")
        for name in ("d_model", "hidden", "heads", "layers", "ff"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.d_model % self.heads:
            raise ValueError(f"d_model ({self.d_model}) must be divisible by heads ({self.heads})")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {self.fps}")

    @classmethod
    def from_dict(cls, d: dict) -> "ContactPredictorConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown contact predictor config keys {unknown}; known keys are {sorted(known)}")
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)


class ContactPredictor(nn.Module):
    """Windows of poses -> per-frame hand contact logits and interaction-class logits."""

    def __init__(self, config: ContactPredictorConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        self.embed = nn.Sequential(nn.Linear(NUM_JOINTS * 6, c.hidden), nn.GELU(), nn.Linear(c.hidden, c.d_model))
        self.pos = nn.Parameter(torch.randn(c.window, c.d_model) * 0.02)  # frame position in the window
        layer = nn.TransformerEncoderLayer(c.d_model, c.heads, c.ff, c.dropout, batch_first=True, norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, c.layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(c.d_model)
        self.contact_head = nn.Linear(c.d_model, len(HANDS))
        self.class_head = nn.Linear(c.d_model, len(CLASSES))

    def forward(self, windows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """windows: (B, W, 24, 6) local 6D rotations (``pose_windows``). Returns contact logits
        (B, W, 2) (left, right) and class logits (B, W, len(CLASSES)); frames attend to frames
        of their own window only."""
        if windows.ndim != 4 or windows.shape[1:] != (self.config.window, NUM_JOINTS, 6):
            raise ValueError(f"windows must be (B, {self.config.window}, 24, 6), got {tuple(windows.shape)}")
        x = self.embed(rearrange(windows, "b w j s -> b w (j s)")) + self.pos  # (B, W, d)
        x = self.norm(self.encoder(x))  # attention over W (batch_first)
        return self.contact_head(x), self.class_head(x)


def mirror_rotations(rot6: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """Left/right mirror of local 6D rotations (..., 24, 6) across the sagittal plane (module doc)."""
    if rot6.shape[-2:] != (NUM_JOINTS, 6):
        raise ValueError(f"rotations must be (..., 24, 6), got {tuple(rot6.shape)}")
    idx = MIRROR_JOINTS
    if isinstance(rot6, torch.Tensor):
        return rot6[..., torch.as_tensor(idx), :] * torch.as_tensor(_SIGN_6D, dtype=rot6.dtype, device=rot6.device)
    return rot6[..., idx, :] * _SIGN_6D.astype(np.asarray(rot6).dtype)


def window_indices(centers: np.ndarray, lo: np.ndarray | int, hi: np.ndarray | int, window: int) -> np.ndarray:
    """Frame indices (N, window) of the windows around ``centers`` (N,), clipped to each centre's
    sequence [lo, hi] (inclusive; the edge frame repeats past the ends)."""
    half = window // 2
    idx = np.asarray(centers)[:, None] + np.arange(-half, half + 1)[None]
    return np.clip(idx, np.asarray(lo).reshape(-1, 1), np.asarray(hi).reshape(-1, 1))


def _yaw_of_root(root6: torch.Tensor) -> torch.Tensor:
    """Heading (rad) of root 6D rotations (..., 6): the hip line is the root's y axis (left), so
    forward = left x z and yaw = atan2(-left_x, left_y) (robust when lying: the hip line stays
    horizontal)."""
    left = root6[..., 3:6]
    return torch.atan2(-left[..., 0], left[..., 1])


def pose_windows(rot6: torch.Tensor, index: np.ndarray | torch.Tensor) -> torch.Tensor:
    """Gather windows and express each in its centre frame's heading.

    rot6: (F, 24, 6) local 6D rotations (one sequence, or several concatenated); index: (N, W)
    frame indices (``window_indices``). Returns (N, W, 24, 6) float32 with the root's yaw
    rotated by minus the centre frame's yaw."""
    if isinstance(index, torch.Tensor):
        index = index.to(device=rot6.device, dtype=torch.long)
    else:
        index = torch.as_tensor(np.asarray(index), dtype=torch.long, device=rot6.device)
    win = rot6[index].clone()  # (N, W, 24, 6)
    yaw = _yaw_of_root(win[:, index.shape[1] // 2, 0])  # (N,)
    c, s = torch.cos(-yaw)[:, None], torch.sin(-yaw)[:, None]
    root = rearrange(win[:, :, 0], "n w (k c) -> n w k c", k=2)  # two columns
    x, y = root[..., 0], root[..., 1]
    rotated = torch.stack([c[..., None] * x - s[..., None] * y, s[..., None] * x + c[..., None] * y, root[..., 2]], -1)
    win[:, :, 0] = rearrange(rotated, "n w k c -> n w (k c)")
    return win


@torch.no_grad()
def predict_contacts(model: ContactPredictor, rotations: np.ndarray, batch_size: int = 2048,
                     stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Sliding-window prediction.

    rotations: (T, 24, 6) local 6D at ``model.config.fps``. Returns contact probabilities (T, 2)
    (left, right) and class probabilities (T, len(CLASSES)), float32. With ``stride`` 1 (the
    paper) each frame takes the centre prediction of its own window; with stride s (odd) one
    window every s frames predicts the s frames around its centre (s times cheaper). The result for
    a frame does not depend on ``batch_size`` or on the other windows in its batch. The windows go
    to the model's device (``load_contact_models(..., device=)``); the results come back as numpy."""
    rot = np.asarray(rotations, dtype=np.float32)
    if rot.ndim != 3 or rot.shape[1:] != (NUM_JOINTS, 6):
        raise ValueError(f"rotations must be (T, 24, 6) local 6D, got {rot.shape}")
    if not np.isfinite(rot).all():
        raise ValueError("rotations contain NaN or inf")
    W = model.config.window
    if batch_size < 1 or stride < 1 or stride % 2 == 0 or stride > W:
        raise ValueError(f"batch_size must be >= 1 and stride odd in [1, {W}], got {batch_size}, {stride}")
    T = len(rot)
    if T == 0:
        return np.zeros((0, len(HANDS)), np.float32), np.zeros((0, len(CLASSES)), np.float32)
    was_training = model.training
    model.eval()
    rt = torch.from_numpy(rot).to(next(model.parameters()).device)
    half = stride // 2
    centers_all = np.arange(half, T + half, stride).clip(max=T - 1)  # window k predicts frames k*s .. k*s+s-1
    probs, cls = [], []
    for start in range(0, len(centers_all), batch_size):
        centers = centers_all[start:start + batch_size]
        logit, class_logit = model(pose_windows(rt, window_indices(centers, 0, T - 1, W)))
        frames = np.arange(stride) - half + W // 2  # positions in the window of the frames kept
        probs.append(torch.sigmoid(logit[:, frames]).reshape(-1, len(HANDS)))
        cls.append(torch.softmax(class_logit[:, frames], dim=-1).reshape(-1, len(CLASSES)))
    model.train(was_training)
    # frame f is predicted by window f // s at position f - (f // s) * s - half relative to its centre
    frame = np.arange(T)
    win, off = frame // stride, frame % stride
    # windows whose centre was clipped at the end: shift the position so it still points at frame f
    pos = win * stride + off - centers_all[win] + half
    flat = win * stride + pos
    return torch.cat(probs).cpu().numpy()[flat], torch.cat(cls).cpu().numpy()[flat]
