"""Typed training configuration loaded from TOML (unknown keys are errors).

Sections: ``[model]`` (denoiser sizes + ablation switches ``scene_condition``, ``action_condition``),
``[scene]`` / ``[action]`` (encoder sizes), ``[diffusion]``, ``[data]`` (episodes, grids, ablation
switches ``progress_indicator``, ``augmented``) and ``[train]`` (optimiser, schedule, masks,
condition dropout). Built-in configs live in ``train/configs/<name>.toml``.
"""
from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from trumans.model.diffusion import DiffusionConfig

__all__ = ["ModelSection", "EncoderSection", "DataSection", "TrainSection", "TrainConfig", "load_config",
           "CONFIG_DIR", "builtin_configs"]

CONFIG_DIR = Path(__file__).parent / "configs"


@dataclass(frozen=True)
class ModelSection:
    """Denoiser: post-LN transformer; scene_condition / action_condition = False are ablations."""

    d_model: int = 512
    layers: int = 8
    heads: int = 16
    ff: int = 1024
    dropout: float = 0.1
    mask_input: bool = True
    scene_condition: bool = True
    action_condition: bool = True


@dataclass(frozen=True)
class EncoderSection:
    """Scene perceiver / action encoder transformer sizes (patch is used by the scene perceiver only)."""

    d_model: int = 512
    layers: int = 6
    heads: int = 16
    ff: int = 1024
    dropout: float = 0.1
    patch: int = 8


@dataclass(frozen=True)
class DataSection:
    """fps: generator rate (data is resampled); episode_frames: L_epi; transition_frames: k; stride:
    frames between episode starts; grid: n; extent: local grid size (m); rotations: add 6D rotations
    to the features; progress_indicator = False drops it (labels become 0/1); augmented = False
    drops sequences the index lists under ``augmented``; dynamic_objects: place the scene's dynamic
    objects at each episode's start (``scenes.scene_grids``; False = the cached occupancy as is);
    max_val_episodes caps the val set."""

    fps: float = 10.0
    episode_frames: int = 16
    transition_frames: int = 2
    stride: int = 2
    grid: int = 32
    extent: tuple[float, float, float] = (1.2, 1.2, 1.2)
    rotations: bool = False
    progress_indicator: bool = True
    augmented: bool = True
    dynamic_objects: bool = True
    max_val_episodes: int = 2048


@dataclass(frozen=True)
class TrainSection:
    """Optimiser (Adam), EMA, clipping, schedule (steps, checkpoint/val intervals), masks, CFG dropout."""

    steps: int = 100_000
    batch_size: int = 64
    lr: float = 1e-4
    weight_decay: float = 0.0
    warmup_steps: int = 0
    ema_decay: float = 0.999
    grad_clip: float = 1.0
    checkpoint_every: int = 1000
    val_every: int = 1000
    val_batch_size: int = 256
    p_trans: float = 0.9
    p_goal_pelvis: float = 0.6
    p_goal_hand: float = 0.2
    p_drop_scene: float = 0.1
    p_drop_action: float = 0.1
    time_limit_s: float = 0.0  # 0 = none; stop (and checkpoint) after this many seconds


@dataclass(frozen=True)
class TrainConfig:
    name: str = "custom"
    model: ModelSection = field(default_factory=ModelSection)
    scene: EncoderSection = field(default_factory=EncoderSection)
    action: EncoderSection = field(default_factory=EncoderSection)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    data: DataSection = field(default_factory=DataSection)
    train: TrainSection = field(default_factory=TrainSection)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, source: str = "config") -> "TrainConfig":
        return _build(cls, d, source)

    def with_overrides(self, **sections: dict) -> "TrainConfig":
        """A copy with ``section={key: value}`` replaced (keys checked)."""
        d = self.to_dict()
        for sec, vals in sections.items():
            if sec not in d or not isinstance(d[sec], dict):
                raise ValueError(f"unknown config section {sec!r}")
            d[sec].update(vals)
        return TrainConfig.from_dict(d)


def _build(cls, d: Any, where: str):
    if not isinstance(d, dict):
        raise ValueError(f"{where} must be a table, got {type(d).__name__}")
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(d) - set(known))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; known keys: {sorted(known)}")
    kwargs = {}
    defaults = cls()
    for k, v in d.items():
        default = getattr(defaults, k)
        if is_dataclass(default):
            kwargs[k] = _build(type(default), v, f"{where}.{k}")
        elif isinstance(default, tuple):
            kwargs[k] = tuple(float(x) for x in v)
        elif isinstance(default, bool):
            if not isinstance(v, bool):
                raise ValueError(f"{where}.{k} must be true/false, got {v!r}")
            kwargs[k] = v
        elif isinstance(default, float) and isinstance(v, (int, float)) and not isinstance(v, bool):
            kwargs[k] = float(v)
        elif isinstance(default, int) and isinstance(v, int) and not isinstance(v, bool):
            kwargs[k] = v
        elif isinstance(default, str) and isinstance(v, str):
            kwargs[k] = v
        else:
            raise ValueError(f"{where}.{k} must be a {type(default).__name__}, got {v!r}")
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from e


def builtin_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.toml"))


def load_config(name_or_path: str | Path) -> TrainConfig:
    """A built-in config name (``cpu-small``, ``paper``) or a TOML file path -> TrainConfig."""
    p = Path(name_or_path)
    if not p.suffix and (CONFIG_DIR / f"{p.name}.toml").is_file():
        p = CONFIG_DIR / f"{p.name}.toml"
    if not p.is_file():
        raise FileNotFoundError(f"config {name_or_path!r} is neither a built-in config {builtin_configs()} "
                                f"nor an existing TOML file")
    try:
        d = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{p} is not valid TOML: {e}") from e
    d.setdefault("name", p.stem)
    return TrainConfig.from_dict(d, source=str(p))
