"""The motion encoder behind the synthesis figures: FID, diversity and action accuracy.

A small 1D-convolutional network over windows of canonical joint positions (10 fps, 32 frames =
3.2 s by default; canonical frame of ``trumans.model.episodes``) trained to classify the window's
dominant action (softmax over the dataset's vocabulary). Its penultimate features give the
Fréchet distance (``fid``) and the mean distance between random pairs (``diversity``), as in the
HumanML3D / MDM evaluation protocol (Guo et al. 2022 §5; Tevet et al. 2023 §5); its head gives
``action_acc``. Training: ``trumans train --task motion_encoder`` (``trumans.train.tasks.motion_encoder``).
Files: the shared checkpoint format (``trumans.model.checkpoint``) with kind "motion_encoder"
(``MOTION_ENCODER_KIND``): ``model_config`` (``MotionEncoderConfig``), ``model`` / ``ema``, ``norm``
(the (144,) input mean / std), ``vocabulary``, ``fps``, ``meta["figures"]`` (the training report:
accuracies, majority baseline, real-vs-real FID / diversity); read with ``weights_only`` and
checked against its digest. The shipped file is ``models/motion_encoder.pt``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np
import torch
from einops import rearrange
from scipy import linalg
from torch import nn

from trumans.actions import remap_labels
from trumans.model.checkpoint import Checkpoint, KindSpec, load_checkpoint, save_checkpoint
from trumans.model.episodes import Normalizer, canonical_frame, canonicalize, episode_starts
from trumans.resample import resample_sequence
from trumans.sequence import Sequence
from trumans.skeleton import NUM_JOINTS
from trumans.paths import MODELS_DIR
from trumans.version import __version__

__all__ = [
    "MotionEncoderConfig",
    "MotionEncoderNet",
    "MotionEncoder",
    "DEFAULT_MOTION_ENCODER",
    "KIND",
    "MOTION_ENCODER_KIND",
    "INPUT_DIM",
    "encoder_checkpoint",
    "save_motion_encoder",
    "load_motion_encoder",
    "split_features",
    "split_features_and_labels",
    "matched_weights",
    "motion_windows",
    "window_inputs",
    "dominant_action",
    "fid",
    "diversity",
    "action_acc",
]

DEFAULT_MOTION_ENCODER = MODELS_DIR / "motion_encoder.pt"
KIND = "motion_encoder"  # its checkpoint kind (trumans.model.checkpoint.KINDS)
INPUT_DIM = 2 * NUM_JOINTS * 3  # per frame: joint positions then velocities (window_inputs)


@dataclass(frozen=True)
class MotionEncoderConfig:
    """fps / window: the input windows (frames at fps); channels: conv widths; feature_dim: the
    penultimate (FID) feature width; num_actions: the head's width (= len(vocabulary))."""

    num_actions: int
    fps: float = 10.0
    window: int = 32
    channels: tuple[int, int, int] = (128, 128, 192)
    feature_dim: int = 128
    dropout: float = 0.1

    def __post_init__(self) -> None:
        for name, ok, need in (("num_actions", self.num_actions >= 1, ">= 1"), ("window", self.window >= 4, ">= 4"),
                               ("fps", self.fps > 0, "> 0"), ("feature_dim", self.feature_dim >= 1, ">= 1")):
            if not ok:
                raise ValueError(f"motion encoder config: {name} must be {need}, got {getattr(self, name)}")

    @classmethod
    def from_dict(cls, d: dict) -> "MotionEncoderConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown motion encoder config keys {unknown}; known: {sorted(known)}")
        d = dict(d)
        if "channels" in d:
            d["channels"] = tuple(int(c) for c in d["channels"])
        return cls(**d)

    def to_dict(self) -> dict:
        return asdict(self)


class MotionEncoderNet(nn.Module):
    """x (B, L, 144) normalised [positions, velocities] -> (features (B, D), logits (B, A))."""

    def __init__(self, cfg: MotionEncoderConfig) -> None:
        super().__init__()
        self.config = cfg
        c1, c2, c3 = cfg.channels
        d_in = INPUT_DIM
        self.convs = nn.Sequential(
            nn.Conv1d(d_in, c1, 5, padding=2), nn.GELU(),
            nn.Conv1d(c1, c2, 5, stride=2, padding=2), nn.GELU(),
            nn.Conv1d(c2, c3, 3, stride=2, padding=1), nn.GELU(),
        )
        self.proj = nn.Linear(2 * c3, cfg.feature_dim)
        self.drop = nn.Dropout(cfg.dropout)
        self.head = nn.Linear(cfg.feature_dim, cfg.num_actions)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.convs(rearrange(x, "b l f -> b f l"))  # (B, C, L/4)
        h = torch.cat([h.mean(-1), h.amax(-1)], dim=-1)  # (B, 2C)
        feats = torch.tanh(self.proj(h))  # (B, D) penultimate features
        return feats, self.head(self.drop(feats))


def window_inputs(windows: np.ndarray, fps: float) -> np.ndarray:
    """Canonical windows (M, L, 24, 3) m -> (M, L, 144): positions then velocities (m/s, first frame repeats)."""
    pos = rearrange(windows, "m l j c -> m l (j c)")
    vel = np.diff(pos, axis=1, prepend=pos[:, :1]) * fps
    vel[:, 0] = vel[:, 1]
    return np.concatenate([pos, vel], axis=-1).astype(np.float32)


def motion_windows(joints: np.ndarray, fps: float, window: int, target_fps: float,
                   stride: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cut one clip into canonical windows.

    joints: (T, 24, 3) m z-up world at ``fps`` -> (windows (W, window, 24, 3) canonical m at
    ``target_fps``, starts (W,) first frames at ``target_fps``); stride defaults to ``window // 2``."""
    joints = np.asarray(joints, np.float32)
    seq = resample_sequence(Sequence(joints=joints, fps=float(fps)), target_fps)
    starts = episode_starts(seq.num_frames, window, stride or max(window // 2, 1))
    w = seq.joints[starts[:, None] + np.arange(window)]  # (W, L, 24, 3)
    if len(w) == 0:
        return np.zeros((0, window, NUM_JOINTS, 3), np.float32), starts
    origin, yaw = canonical_frame(w)
    return canonicalize(w, origin, yaw), starts


def dominant_action(actions: np.ndarray, fps: float, window: int, target_fps: float,
                    stride: int | None = None) -> np.ndarray:
    """Per window of ``motion_windows`` (same fps/window/stride), the action on in the most frames.

    actions: (T, A) labels (0 off, 1 + progress on) at ``fps`` -> (W,) int, -1 where none is on."""
    a = np.asarray(actions, np.float32)
    seq = resample_sequence(Sequence(joints=np.zeros((len(a), NUM_JOINTS, 3), np.float32), fps=float(fps),
                                     actions=a, action_names=[str(i) for i in range(a.shape[1])]), target_fps)
    starts = episode_starts(seq.num_frames, window, stride or max(window // 2, 1))
    on = (seq.actions[starts[:, None] + np.arange(window)] > 0).sum(1)  # (W, A) frames on
    return np.where(on.max(-1) > 0, on.argmax(-1), -1).astype(np.int64)


class MotionEncoder:
    """A trained encoder: ``encode`` (features), ``classify`` (action probabilities), the vocabulary."""

    def __init__(self, cfg: MotionEncoderConfig, net: MotionEncoderNet, mean: np.ndarray, std: np.ndarray,
                 vocabulary: list[str], info: dict | None = None) -> None:
        if len(vocabulary) != cfg.num_actions:
            raise ValueError(f"vocabulary has {len(vocabulary)} names but the config {cfg.num_actions} actions")
        self.cfg, self.net = cfg, net.eval()
        self.mean, self.std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
        self.vocabulary = list(vocabulary)
        self.info = dict(info or {})

    def _run(self, joints: np.ndarray, fps: float, stride: int | None) -> tuple[np.ndarray, np.ndarray]:
        joints = np.asarray(joints, np.float32)
        if joints.ndim == 3:
            joints = joints[None]
        if joints.ndim != 4 or joints.shape[-2:] != (NUM_JOINTS, 3):
            raise ValueError(f"joints must be (N, T, 24, 3) (or one (T, 24, 3) clip), got {joints.shape}")
        per = [motion_windows(j, fps, self.cfg.window, self.cfg.fps, stride)[0] for j in joints]
        if len(per[0]) == 0:
            span = self.cfg.window / self.cfg.fps
            raise ValueError(f"clips of {joints.shape[1]} frames at {fps} fps are shorter than the encoder's "
                             f"{span:g} s window; pass longer clips")
        x = (window_inputs(np.concatenate(per), self.cfg.fps) - self.mean) / self.std
        with torch.inference_mode():
            feats, logits = [], []
            for chunk in torch.from_numpy(x).split(512):
                f, lg = self.net(chunk)
                feats.append(f)
                logits.append(lg)
        n, w = len(joints), len(per[0])
        f = torch.cat(feats).numpy().reshape(n, w, -1)
        p = torch.cat(logits).softmax(-1).numpy().reshape(n, w, -1)
        return f, p

    def encode(self, joints: np.ndarray, fps: float, stride: int | None = None) -> np.ndarray:
        """joints (N, T, 24, 3) m z-up world at ``fps`` -> features (N, W, D): one per window of
        ``cfg.window`` frames at ``cfg.fps`` every ``stride`` frames (default window // 2)."""
        return self._run(joints, fps, stride)[0]

    def classify(self, joints: np.ndarray, fps: float, stride: int | None = None) -> np.ndarray:
        """joints (N, T, 24, 3) -> action probabilities (N, W, A) per window (columns: ``vocabulary``)."""
        return self._run(joints, fps, stride)[1]

    def window_labels(self, actions: np.ndarray, action_names: list[str], fps: float,
                      stride: int | None = None) -> np.ndarray:
        """Dominant action per window (N, W) in this encoder's vocabulary (-1: none on), for the same
        windows as ``encode``. actions: (N, T, A) or (T, A) labels whose columns are ``action_names``."""
        a = np.asarray(actions, np.float32)
        if a.ndim == 2:
            a = a[None]
        if a.ndim != 3 or a.shape[-1] != len(action_names):
            raise ValueError(f"actions must be (N, T, {len(action_names)}) to match action_names, got {a.shape}")
        return np.stack([dominant_action(remap_labels(x, list(action_names), self.vocabulary), fps, self.cfg.window,
                                         self.cfg.fps, stride) for x in a])

    def checkpoint(self, data: dict | None = None, meta: dict | None = None) -> Checkpoint:
        """This encoder as a checkpoint of kind "motion_encoder" (an export: its weights, no EMA or
        training state); ``meta["figures"]`` is ``info``."""
        state = {k: v.detach().cpu().clone() for k, v in self.net.state_dict().items()}
        return encoder_checkpoint(self.cfg, state, Normalizer(self.mean, self.std), self.vocabulary, data=data,
                                  meta={**(meta or {}), "figures": dict(self.info)})


def _check(ck: Checkpoint) -> None:
    cfg: MotionEncoderConfig = ck.model_config
    if ck.normalizer.mean.shape != (INPUT_DIM,):
        raise ValueError(f"its input normalisation has {ck.normalizer.mean.shape[0]} features, the encoder reads "
                         f"{INPUT_DIM}; the checkpoint is inconsistent - retrain it")
    if len(ck.vocabulary) != cfg.num_actions:
        raise ValueError(f"its vocabulary has {len(ck.vocabulary)} actions but the head {cfg.num_actions}; "
                         f"the checkpoint is inconsistent - retrain it")
    if abs(float(ck.fps) - cfg.fps) > 1e-9:
        raise ValueError(f"its fps {ck.fps} differs from its model config's {cfg.fps}; the checkpoint is inconsistent")


MOTION_ENCODER_KIND = KindSpec(config_from_dict=MotionEncoderConfig.from_dict, build=MotionEncoderNet,
                               required=("norm", "vocabulary", "fps"), check=_check)


def encoder_checkpoint(cfg: MotionEncoderConfig, model_state: dict, normalizer: Normalizer, vocabulary: list[str], *,
                       ema_state: dict | None = None, data: dict | None = None, meta: dict | None = None,
                       train_state: dict | None = None) -> Checkpoint:
    """The checkpoint (kind "motion_encoder") of an encoder: weights as CPU state dicts, the (144,)
    input normalisation, the action vocabulary (the head's columns)."""
    return Checkpoint(kind=KIND, model_config=cfg, model_state=model_state, ema_state=ema_state, normalizer=normalizer,
                      vocabulary=list(vocabulary), fps=float(cfg.fps), data=dict(data or {}), meta=dict(meta or {}),
                      train_state=train_state, code_version=__version__)


def save_motion_encoder(enc: MotionEncoder, path: str | Path, data: dict | None = None, meta: dict | None = None) -> None:
    """Write ``enc`` as an export (``MotionEncoder.checkpoint``) to ``path`` atomically."""
    save_checkpoint(path, enc.checkpoint(data, meta))


_RETIRED_FORMAT = "trumans-motion-encoder-1"  # the private format before kind "motion_encoder"


def load_motion_encoder(path: str | Path | None = None) -> MotionEncoder:
    """Load a motion encoder checkpoint (default: the shipped ``models/motion_encoder.pt``; a
    training run's ``RUN/checkpoint.pt``: its EMA weights) without running code. ``info`` of the
    result is the checkpoint's ``meta["figures"]`` (empty when it has none)."""
    path = Path(path) if path is not None else DEFAULT_MOTION_ENCODER
    if not path.exists():
        raise FileNotFoundError(f"motion encoder {path} does not exist; train one with "
                                f"`trumans train --task motion_encoder --data DATASET --out RUN` (RUN/checkpoint.pt)")
    try:
        ck = load_checkpoint(path, kind=KIND)
    except ValueError as e:
        if _is_retired(path):
            raise ValueError(f"{path} is a motion encoder in the retired format {_RETIRED_FORMAT!r}; convert it "
                             f"(same weights) with `python scripts/ship_motion_encoder.py {path} --out NEW.pt`") from None
        raise ValueError(f"motion encoder: {e}") from None
    net = ck.build_model()
    return MotionEncoder(ck.model_config, net, ck.normalizer.mean, ck.normalizer.std, ck.vocabulary,
                         ck.meta.get("figures"))


def _is_retired(path: Path) -> bool:
    try:
        d = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # noqa: BLE001 - unreadable: not the retired format either
        return False
    return isinstance(d, dict) and d.get("format") == _RETIRED_FORMAT


def split_features_and_labels(enc: MotionEncoder, data, split: str) -> tuple[np.ndarray, np.ndarray]:
    """Features (N, D) and dominant-action labels (N,) (encoder vocabulary, -1: none on) of every
    window of a dataset split's clips (a ``trumans.dataset.Dataset``); clips shorter than the
    encoder's window are skipped (they have no window)."""
    span = enc.cfg.window / enc.cfg.fps
    feats, labels = [], []
    for s in map(data.load, data.split(split)):
        if s.num_frames / s.fps < span:
            continue
        feats.append(enc.encode(s.joints[None], s.fps)[0])
        if s.actions is None:
            labels.append(np.full(len(feats[-1]), -1, np.int64))
        else:
            labels.append(enc.window_labels(s.actions, list(s.action_names), s.fps)[0])
    if not feats:
        raise ValueError(f"split {split!r} of {data.root} has no clip of at least {span:.1f} s for the motion encoder")
    return np.concatenate(feats), np.concatenate(labels)


def split_features(enc: MotionEncoder, data, split: str) -> np.ndarray:
    """Features (N, D) of every window of a dataset split's clips (``split_features_and_labels`` without labels)."""
    return split_features_and_labels(enc, data, split)[0]


def matched_weights(real_labels: np.ndarray, gen_labels: np.ndarray) -> np.ndarray:
    """Weights (N,) of real windows that give them the generated windows' action histogram
    (labels: dominant action per window, -1 = none on, a class of its own). Real windows of an
    action the generated set lacks get 0; generated actions absent from the real set are left out
    (the returned weights sum to 1 over the shared actions)."""
    r, g = np.asarray(real_labels).ravel(), np.asarray(gen_labels).ravel()
    if len(r) == 0 or len(g) == 0:
        raise ValueError(f"need real and generated window labels, got {len(r)} and {len(g)}")
    acts, g_count = np.unique(g, return_counts=True)
    shared = np.isin(acts, r)
    if not shared.any():
        raise ValueError("no action of the generated windows occurs in the real windows; nothing to match")
    target = dict(zip(acts[shared].tolist(), (g_count[shared] / g_count[shared].sum()).tolist()))
    r_count = dict(zip(*np.unique(r, return_counts=True)))
    return np.array([target.get(a, 0.0) / r_count[a] for a in r.tolist()])


def like_sample(pool_labels: np.ndarray, gen_labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices into a pool of windows (labels (N,)) that draw, per action, as many windows as the
    generated set has (labels (M,)); without replacement where the pool has enough, else with.
    Generated actions the pool lacks are left out. A real set of the generated set's size and
    action mix: Fréchet distances of small sets are biased upward (the covariance of a few dozen
    128-d features), so the real-vs-real value to compare with is taken at the same size."""
    pool, gen = np.asarray(pool_labels).ravel(), np.asarray(gen_labels).ravel()
    out = []
    for a, c in zip(*np.unique(gen, return_counts=True)):
        have = np.flatnonzero(pool == a)
        if len(have):
            out.append(rng.choice(have, int(c), replace=len(have) < c))
    if not out:
        raise ValueError("no action of the generated windows occurs in the pool; nothing to draw")
    return np.concatenate(out)


def _flat(feats: np.ndarray, what: str) -> np.ndarray:
    f = np.asarray(feats, np.float64)
    if f.ndim < 2:
        raise ValueError(f"{what} must be (..., D) features, got {f.shape}")
    return f.reshape(-1, f.shape[-1])


def _weighted(x: np.ndarray, w: np.ndarray | None, what: str) -> tuple[np.ndarray, np.ndarray | None]:
    if w is None:
        return x, None
    w = np.asarray(w, np.float64).ravel()
    if w.shape != (len(x),) or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise ValueError(f"{what} must be ({len(x)},) finite, >= 0 and not all 0, got shape {w.shape}")
    return x[w > 0], w[w > 0]


def fid(real_feats: np.ndarray, gen_feats: np.ndarray, real_weights: np.ndarray | None = None,
        gen_weights: np.ndarray | None = None) -> float:
    """Fréchet distance between Gaussians fitted to two feature sets (..., D) (Heusel et al. 2017):
    ``|mu_r - mu_g|^2 + Tr(S_r + S_g - 2 (S_r S_g)^(1/2))``. real_weights / gen_weights: optional
    (N,) sample weights of either set (``matched_weights``: a set's Gaussian under another action mix)."""
    a, b = _flat(real_feats, "real_feats"), _flat(gen_feats, "gen_feats")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"feature widths differ: {a.shape[1]} vs {b.shape[1]}")
    (a, wa), (b, wb) = _weighted(a, real_weights, "real_weights"), _weighted(b, gen_weights, "gen_weights")
    if len(a) < 2 or len(b) < 2:
        raise ValueError(f"fid needs at least 2 samples per set, got {len(a)} and {len(b)}")
    mu_a, mu_b = np.average(a, axis=0, weights=wa), np.average(b, axis=0, weights=wb)
    s_a, s_b = np.cov(a, rowvar=False, aweights=wa), np.cov(b, rowvar=False, aweights=wb)
    covmean = linalg.sqrtm(s_a @ s_b)
    if not np.isfinite(covmean).all():  # singular product: regularise (as pytorch-fid does)
        eps = 1e-6 * np.eye(len(s_a))
        covmean = linalg.sqrtm((s_a + eps) @ (s_b + eps))
    covmean = np.real(covmean)
    return float(max(((mu_a - mu_b) ** 2).sum() + np.trace(s_a + s_b - 2 * covmean), 0.0))


def diversity(feats: np.ndarray, pairs: int = 300, seed: int = 0) -> float:
    """Mean Euclidean distance between ``pairs`` random pairs of features (..., D) (MDM protocol;
    two index draws without replacement when there are enough samples, else with)."""
    f = _flat(feats, "feats")
    if len(f) < 2:
        raise ValueError(f"diversity needs at least 2 samples, got {len(f)}")
    if pairs < 1:
        raise ValueError(f"pairs must be >= 1, got {pairs}")
    rng = np.random.default_rng(seed)
    replace = pairs > len(f)
    i, j = rng.choice(len(f), pairs, replace=replace), rng.choice(len(f), pairs, replace=replace)
    return float(np.linalg.norm(f[i] - f[j], axis=-1).mean())


def action_acc(probs: np.ndarray, labels: np.ndarray) -> float:
    """Fraction of windows whose most probable action is ``labels`` (probs (..., A), labels (...) int;
    windows labelled -1, none on, are skipped)."""
    p, y = np.asarray(probs), np.asarray(labels)
    if p.shape[:-1] != y.shape:
        raise ValueError(f"probs {p.shape} and labels {y.shape} disagree; labels must be probs.shape[:-1]")
    keep = y >= 0
    if not keep.any():
        raise ValueError("no labelled window (all labels are -1)")
    return float((p.argmax(-1)[keep] == y[keep]).mean())
