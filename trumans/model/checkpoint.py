"""Checkpoint files (``.pt``, DESIGN.md "Files"): weights plus everything needed to use them.

A checkpoint is a plain dict of tensors / str / int / float / lists / dicts, written atomically
with ``torch.save`` and read with ``torch.load(weights_only=True)`` (never executes code):

``format`` ("trumans-checkpoint"), ``format_version``, ``kind`` ("generator", ...),
``code_version``, ``model_config`` (``DenoiserConfig.to_dict()``), ``diffusion_config``,
``model`` (state dict), ``ema`` (state dict or None), ``norm`` ({"mean", "std"} tensors),
``vocabulary`` (action names), ``fps``, ``L_epi``, ``k``, ``grid`` ({"n", "extent"}),
``data`` ({"name", "hash", "path"}), ``meta`` (free dict: training config, figures), and
``train_state`` (optimizer state, step, loss history; None in an export).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import torch

from trumans import __version__
from .diffusion import DiffusionConfig, GaussianDiffusion
from .episodes import Normalizer
from .nets.denoiser import Denoiser, DenoiserConfig
from trumans.sequence import atomic_write

__all__ = ["Checkpoint", "save_checkpoint", "load_checkpoint", "FORMAT", "FORMAT_VERSION"]

FORMAT = "trumans-checkpoint"
FORMAT_VERSION = 1


@dataclass
class Checkpoint:
    """Everything a checkpoint holds; ``build_model()`` rebuilds the network from it."""

    kind: str
    model_config: DenoiserConfig
    diffusion_config: DiffusionConfig
    model_state: dict[str, torch.Tensor]
    normalizer: Normalizer
    vocabulary: list[str]
    fps: float
    L_epi: int
    k: int
    grid: dict
    data: dict = field(default_factory=dict)
    ema_state: dict[str, torch.Tensor] | None = None
    meta: dict = field(default_factory=dict)
    train_state: dict | None = None
    code_version: str = __version__

    def build_model(self, ema: bool = True) -> Denoiser:
        """The denoiser with the EMA weights (if present and ``ema``) or the raw weights, in eval mode."""
        model = Denoiser(self.model_config)
        state = self.ema_state if ema and self.ema_state is not None else self.model_state
        try:
            model.load_state_dict(state)
        except RuntimeError as e:
            raise ValueError(f"checkpoint weights do not match its model config ({str(e).splitlines()[0]}); "
                             f"the file is inconsistent - re-export or retrain it") from e
        return model.eval()

    def build_diffusion(self) -> GaussianDiffusion:
        return GaussianDiffusion(self.diffusion_config)


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> None:
    """Write ``ckpt`` to ``path`` atomically (temp file, then rename)."""
    payload = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "kind": ckpt.kind,
        "code_version": ckpt.code_version,
        "model_config": ckpt.model_config.to_dict(), "diffusion_config": ckpt.diffusion_config.to_dict(),
        "model": ckpt.model_state, "ema": ckpt.ema_state, "norm": ckpt.normalizer.state_dict(),
        "vocabulary": list(ckpt.vocabulary), "fps": float(ckpt.fps), "L_epi": int(ckpt.L_epi), "k": int(ckpt.k),
        "grid": dict(ckpt.grid), "data": dict(ckpt.data), "meta": dict(ckpt.meta), "train_state": ckpt.train_state,
    }
    atomic_write(path, lambda tmp: torch.save(payload, tmp))


_REQUIRED = ("kind", "model_config", "diffusion_config", "model", "norm", "vocabulary", "fps", "L_epi", "k", "grid")


def load_checkpoint(path: str | Path, kind: str | None = "generator") -> Checkpoint:
    """Read a checkpoint (``weights_only=True``). ``kind``: the expected kind (None = any).

    Raises FileNotFoundError for a missing file and ValueError, naming the problem and the fix,
    for a corrupt/foreign file, a newer format, a different kind or an inconsistent config.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist; train one with `trumans train --out RUN` "
                                f"(it writes RUN/checkpoint.pt)")
    try:
        d = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # corrupt bytes surface as many types (UnpicklingError, RuntimeError, IndexError, ...)
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        if "weights only load failed" in msg.lower():  # torch's text goes on to suggest unsafe loading: never
            msg = "it holds objects other than tensors and plain data; refused, loading them could run code"
        raise ValueError(f"{path} is not a readable trumans checkpoint ({msg}); it is corrupt, truncated or "
                         f"not a checkpoint - use the RUN/checkpoint.pt written by `trumans train`") from e
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"{path} is a torch file but not a trumans checkpoint (no format={FORMAT!r}); "
                         f"use the RUN/checkpoint.pt written by `trumans train`")
    if int(d.get("format_version", 0)) > FORMAT_VERSION:
        raise ValueError(f"{path} has checkpoint format {d.get('format_version')}, newer than this code's "
                         f"{FORMAT_VERSION}; update trumans")
    missing = [k for k in _REQUIRED if k not in d]
    if missing:
        raise ValueError(f"{path} lacks {missing}; the checkpoint is incomplete - retrain or re-export it")
    if kind is not None and d["kind"] != kind:
        raise ValueError(f"{path} is a {d['kind']!r} checkpoint, but a {kind!r} checkpoint is needed here")
    try:
        model_config = DenoiserConfig.from_dict(d["model_config"])
        diffusion_config = DiffusionConfig(**d["diffusion_config"])
        norm = Normalizer.from_state_dict(d["norm"])
    except (TypeError, ValueError, KeyError) as e:
        raise ValueError(f"{path} has an invalid model/diffusion config or normalisation ({e}); "
                         f"it was written by an incompatible version - retrain it") from e
    if norm.mean.shape[0] != model_config.feature_dim:
        raise ValueError(f"{path}: normalisation has {norm.mean.shape[0]} features but the model expects "
                         f"{model_config.feature_dim}; the checkpoint is inconsistent")
    if model_config.action is not None and model_config.action.num_actions != len(d["vocabulary"]):
        raise ValueError(f"{path}: the action encoder takes {model_config.action.num_actions} actions but the "
                         f"vocabulary has {len(d['vocabulary'])}; the checkpoint is inconsistent")
    return Checkpoint(
        kind=d["kind"], model_config=model_config, diffusion_config=diffusion_config, model_state=d["model"],
        normalizer=norm, vocabulary=[str(v) for v in d["vocabulary"]], fps=float(d["fps"]),
        L_epi=int(d["L_epi"]), k=int(d["k"]), grid=dict(d["grid"]), data=dict(d.get("data", {})),
        ema_state=d.get("ema"), meta=dict(d.get("meta", {})), train_state=d.get("train_state"),
        code_version=str(d.get("code_version", "")),
    )
