"""Typed training configuration loaded from TOML (unknown keys are errors).

One config per component, nested (never mirrored field by field): the generator's TOML sections
are ``[model]`` (``DenoiserConfig``), ``[scene]`` (``ScenePerceiverConfig``), ``[action]``
(``ActionEncoderConfig``), ``[diffusion]`` (``DiffusionConfig``: steps, schedule, prediction,
loss, ...), ``[conditions]`` (ablation switches ``scene``, ``action``), ``[data]`` (episodes, grids,
ablation switches ``progress_indicator``, ``augmented``) and ``[train]`` (``TrainSection``: the
optimisation - Adam, warm-up, EMA, clipping, cadence, masks, condition dropout - shared by every
task). Fields that the data decide (the denoiser's frames and layout, the grid size, the action
vocabulary size) are filled in from ``[data]`` and the dataset, and are errors in a file.
Built-in configs live in ``train/configs/<name>.toml``.
"""
from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from trumans.config_data import config_from_dict
from trumans.input_files import file_kind, parse_toml
from trumans.limits import check_batch, check_grid, transformer_activation_bytes
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import FeatureLayout
from trumans.model.nets import ActionEncoderConfig, DenoiserConfig, ScenePerceiverConfig

__all__ = ["TrainSection", "DataSection", "ConditionsSection", "GeneratorConfig", "TrainConfig", "load_config",
           "load_toml", "CONFIG_DIR", "builtin_configs"]

CONFIG_DIR = Path(__file__).parent / "configs"


def _need(ok: bool, msg: str) -> None:
    if not ok:
        raise ValueError(msg)


@dataclass(frozen=True)
class TrainSection:
    """Optimisation, shared by every task: the optimizer ("adam": weight_decay is an L2 term added
    to the gradient, torch's Adam; "adamw": decoupled weight decay, Loshchilov & Hutter 2019 §2),
    lr, weight_decay, linear warm-up, EMA decay in [0, 1), gradient clipping (0 = off), steps,
    checkpoint / validation intervals, batch sizes, the inpainting-mask probabilities, condition
    dropout (classifier-free guidance), a time limit in seconds (0 = none; the run stops and
    checkpoints after it) and, for the generator, ``seam_weight``: the weight of the seam-continuity
    term (``trumans.train.tasks.generator.seam_loss``; 0 = off, the paper's loss alone); ``precision``:
    "bf16" runs the forward and loss under ``torch.autocast`` in bfloat16 (weights, optimiser state
    and gradients stay float32: mixed precision for GPUs; on CPUs without bf16 units it is slower)."""

    optimizer: Literal["adam", "adamw"] = "adam"
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
    time_limit_s: float = 0.0
    seam_weight: float = 0.0
    precision: Literal["fp32", "bf16"] = "fp32"

    def __post_init__(self) -> None:
        _need(self.precision in ("fp32", "bf16"), f"precision must be 'fp32' or 'bf16', got {self.precision!r}")
        _need(self.seam_weight >= 0, f"seam_weight must be >= 0 (0 = off), got {self.seam_weight}")
        _need(self.steps >= 0, f"steps must be >= 0, got {self.steps}")
        for name in ("checkpoint_every", "val_every"):
            _need(getattr(self, name) >= 1, f"{name} must be >= 1, got {getattr(self, name)}")
        check_batch(self.batch_size, what="batch_size")
        check_batch(self.val_batch_size, what="val_batch_size")
        _need(self.lr > 0, f"lr must be > 0, got {self.lr}")
        _need(self.weight_decay >= 0 and self.warmup_steps >= 0 and self.grad_clip >= 0,
              f"weight_decay, warmup_steps and grad_clip must be >= 0 (grad_clip 0 = off), got "
              f"{self.weight_decay}, {self.warmup_steps}, {self.grad_clip}")
        _need(0 <= self.ema_decay < 1, f"ema_decay must be in [0, 1), got {self.ema_decay}")
        for name in ("p_trans", "p_goal_pelvis", "p_goal_hand", "p_drop_scene", "p_drop_action"):
            _need(0 <= getattr(self, name) <= 1, f"{name} must be a probability in [0, 1], got {getattr(self, name)}")
        _need(self.time_limit_s >= 0, f"time_limit_s must be >= 0 seconds (0 = no limit), got {self.time_limit_s}")


@dataclass(frozen=True)
class DataSection:
    """fps: generator rate (data is resampled); episode_frames: L_epi; transition_frames: k; stride:
    frames between episode starts; grid: n; extent: local grid size (m); rotations: add 6D rotations
    to the features; progress_indicator = False drops it (labels become 0/1); augmented = False
    drops sequences the index lists under ``augmented``; dynamic_objects: place the scene's dynamic
    objects at each episode's start (``trumans.scenes.scene_grids``; False = the cached occupancy as is);
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
    augmented_share: float | None = None
    dynamic_objects: bool = True
    max_val_episodes: int = 2048

    def __post_init__(self) -> None:
        _need(self.fps > 0, f"fps must be > 0, got {self.fps}")
        _need(self.episode_frames >= 2, f"episode_frames must be >= 2, got {self.episode_frames}")
        _need(0 <= self.transition_frames < self.episode_frames,
              f"transition_frames must be in [0, episode_frames), got {self.transition_frames}")
        _need(self.stride >= 1 and self.max_val_episodes >= 1,
              f"stride and max_val_episodes must be >= 1, got {self.stride}, {self.max_val_episodes}")
        check_grid(self.grid, "grid")
        _need(len(self.extent) == 3 and all(e > 0 for e in self.extent), f"extent must be 3 sizes > 0 m, got {self.extent}")
        _need(self.augmented_share is None or 0 <= self.augmented_share <= 1,
              f"augmented_share must be a fraction in [0, 1] (or left out), got {self.augmented_share}")


@dataclass(frozen=True)
class ConditionsSection:
    """Which conditions the generator has; False is the paper's ablation (no scene / no action encoder)."""

    scene: bool = True
    action: bool = True


# keys the data decide: refused in a file, filled in by ``GeneratorConfig.__post_init__`` / the task
_DERIVED = {
    "model": {"layout": "data.rotations", "frames": "data.episode_frames", "scene": "[scene] and conditions.scene",
              "action": "[action] and conditions.action", "extra_features": "the generator (0)",
              "frame_cond_dim": "the generator (0)"},
    "scene": {"grid": "data.grid"},
    "action": {"frames": "data.episode_frames", "num_actions": "the dataset's vocabulary"},
}


@dataclass(frozen=True)
class GeneratorConfig:
    """The generator's training config (TRUMANS §4): component configs nested as they are.

    ``model`` is the complete ``DenoiserConfig`` but for the action vocabulary size, which comes
    from the dataset: use ``denoiser_config(num_actions)``."""

    name: str = "custom"
    model: DenoiserConfig = field(default_factory=DenoiserConfig)
    scene: ScenePerceiverConfig = field(default_factory=ScenePerceiverConfig)
    action: ActionEncoderConfig = field(default_factory=lambda: ActionEncoderConfig(num_actions=1))
    conditions: ConditionsSection = field(default_factory=ConditionsSection)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    data: DataSection = field(default_factory=DataSection)
    train: TrainSection = field(default_factory=TrainSection)

    def __post_init__(self) -> None:
        d = self.data
        scene = replace(self.scene, grid=d.grid)
        action = replace(self.action, frames=d.episode_frames)
        object.__setattr__(self, "scene", scene)
        object.__setattr__(self, "action", action)
        object.__setattr__(self, "model", replace(
            self.model, layout=FeatureLayout(rotations=d.rotations), frames=d.episode_frames, extra_features=0,
            frame_cond_dim=0, scene=scene if self.conditions.scene else None,
            action=action if self.conditions.action else None))
        for name in ("batch_size", "val_batch_size"):
            check_batch(getattr(self.train, name), self.sample_bytes(), f"train.{name}")

    def sample_bytes(self) -> int:
        """Bytes one training sample takes (an estimate, checked against ``trumans.limits.MAX_BATCH_BYTES``
        before anything is allocated): its float32 scene grid plus the activations each transformer
        keeps for the backward pass (``trumans.limits.transformer_activation_bytes``)."""
        m = self.model
        total = transformer_activation_bytes(m.frames + 1, m.d_model, m.layers, m.heads, m.ff)
        if m.scene is not None:
            s = m.scene
            total += 4 * s.grid ** 3 + transformer_activation_bytes((s.grid // s.patch) ** 2 + 1, s.d_model,
                                                                   s.layers, s.heads, s.ff)
        if m.action is not None:
            a = m.action
            total += transformer_activation_bytes(a.frames, a.d_model, a.layers, a.heads, a.ff)
        return total

    def denoiser_config(self, num_actions: int) -> DenoiserConfig:
        """The denoiser config for a vocabulary of ``num_actions`` actions."""
        if self.model.action is None:
            return self.model
        return replace(self.model, action=replace(self.model.action, num_actions=num_actions))

    def to_dict(self) -> dict:
        """Plain data without the derived keys (``from_dict`` inverts it)."""
        d = asdict(self)
        for sec, keys in _DERIVED.items():
            for k in keys:
                d[sec].pop(k, None)
        return d

    @classmethod
    def from_dict(cls, d: dict, source: str = "config") -> "GeneratorConfig":
        return config_from_dict(cls, _migrate(d), source, derived=_DERIVED)

    def with_overrides(self, **sections: dict) -> "GeneratorConfig":
        """A copy with ``section={key: value}`` replaced (keys checked)."""
        return override_sections(self, sections)


TrainConfig = GeneratorConfig  # the name the README and older code use


def override_sections(config, sections: dict[str, dict]):
    """A copy of a sectioned config (``to_dict`` / ``from_dict``) with ``section={key: value}``
    replaced; unknown sections are errors, keys are checked by ``from_dict``."""
    d = config.to_dict()
    for sec, vals in sections.items():
        if sec not in d or not isinstance(d[sec], dict):
            raise ValueError(f"unknown config section {sec!r}; sections: {sorted(k for k in d if isinstance(d[k], dict))}")
        d[sec].update(vals)
    return type(config).from_dict(d)


def _migrate(d: Any) -> Any:
    """Configs saved before the components were nested (checkpoints' train_state): ablation
    switches lived in [model], [action] had an unused ``patch``."""
    if not isinstance(d, dict):
        return d
    d = {k: dict(v) if isinstance(v, dict) else v for k, v in d.items()}
    model = d.get("model", {})
    if isinstance(model, dict) and ("scene_condition" in model or "action_condition" in model):
        cond = d.setdefault("conditions", {})
        if "scene_condition" in model:
            cond["scene"] = model.pop("scene_condition")
        if "action_condition" in model:
            cond["action"] = model.pop("action_condition")
        if isinstance(d.get("action"), dict):
            d["action"].pop("patch", None)
    return d


def builtin_configs() -> list[str]:
    return sorted(p.stem for p in CONFIG_DIR.glob("*.toml"))


def load_toml(name_or_path: str | Path, config_dir: Path = CONFIG_DIR) -> tuple[dict, Path]:
    """A built-in config name (a file in ``config_dir``) or a TOML path -> (its table with ``name``, path)."""
    p = Path(name_or_path)
    if not p.suffix and (config_dir / f"{p.name}.toml").is_file():
        p = config_dir / f"{p.name}.toml"
    if file_kind(p) not in (None, "file"):
        raise ValueError(f"config {p} is a {file_kind(p)}, not a TOML file; pass a built-in config name or a .toml file")
    if not p.is_file():
        raise FileNotFoundError(f"config {name_or_path!r} is neither a built-in config "
                                f"{sorted(q.stem for q in config_dir.glob('*.toml'))} nor an existing TOML file")
    try:
        d = parse_toml(p.read_text(), f"config {p}", "a config's tables nest two or three levels (see the built-in ones)")
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{p} is not valid TOML: {e}") from e
    d.setdefault("name", p.stem)
    return d, p


def load_config(name_or_path: str | Path) -> GeneratorConfig:
    """A built-in generator config name (``cpu-small``, ``paper``) or a TOML file path -> GeneratorConfig."""
    d, p = load_toml(name_or_path)
    return GeneratorConfig.from_dict(d, source=str(p))
