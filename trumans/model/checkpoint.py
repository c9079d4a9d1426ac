"""Checkpoint files (``.pt``, docs/conventions.md "File formats"): weights plus everything needed to use them.

A checkpoint is a plain dict of tensors / str / int / float / lists / dicts, written atomically
with ``torch.save`` and read with ``torch.load(weights_only=True)`` (never executes code):

``format`` ("trumans-checkpoint"), ``format_version``, ``kind`` (``CheckpointKind``: "generator",
"filter", "contact" or "motion_encoder"; files without one are generators), ``code_version``, ``model_config`` (the
kind's model config ``to_dict()``), ``model`` (state dict), ``ema`` (state dict or None),
``diffusion_config``, ``norm`` ({"mean", "std"} tensors), ``vocabulary`` (action names), ``fps``,
``L_epi``, ``k``, ``grid`` ({"n", "extent"}) - each present when set -, ``extra`` (the kind's own
plain-data fields), ``data`` ({"name", "hash", "path"}), ``meta`` (free dict: training config,
figures), ``train_state`` (optimizer state, step, loss history; None in an export), and
``digest``: SHA-256 of everything else (tensors' dtype, shape and bytes; plain values' repr), checked
on load - torch's zip reader does not notice altered tensor bytes, so without it a corrupted file
would load silently. A file without a digest is refused; ``resign_checkpoint`` (``python -m
trumans.model.checkpoint FILE``) signs a file its owner trusts.

``KINDS`` is the one table of kinds: each names the ``KindSpec`` (the model config class, the model
builder, the payload keys the kind requires and a consistency check) of the module that owns the
model, imported when a checkpoint of that kind is first saved or loaded - so no import registers
anything as a side effect. ``register_kind`` adds or replaces one (a user's own model kind).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Literal, get_args

import hashlib
import importlib

import torch
from torch import nn

from trumans.version import __version__
from trumans.input_files import check_input_file
from trumans.sequence import atomic_write
from .diffusion import DiffusionConfig, GaussianDiffusion
from .episodes import Normalizer
from .nets.denoiser import Denoiser, DenoiserConfig

__all__ = ["Checkpoint", "CheckpointKind", "KindSpec", "KINDS", "register_kind", "save_checkpoint", "load_checkpoint",
           "shipped_data_record", "resign_checkpoint",
           "FORMAT", "FORMAT_VERSION", "COMMON_KEYS"]

FORMAT = "trumans-checkpoint"
FORMAT_VERSION = 1
CheckpointKind = Literal["generator", "filter", "contact", "motion_encoder"]
COMMON_KEYS = ("model_config", "model")  # every kind's payload has these


@dataclass
class Checkpoint:
    """Everything a checkpoint holds; ``build_model()`` rebuilds the network from it. Fields after
    ``model_state`` are optional in general; the kind's ``KindSpec.required`` says which it needs."""

    kind: CheckpointKind
    model_config: Any
    model_state: dict[str, torch.Tensor]
    diffusion_config: DiffusionConfig | None = None
    normalizer: Normalizer | None = None
    vocabulary: list[str] | None = None
    fps: float | None = None
    L_epi: int | None = None
    k: int | None = None
    grid: dict | None = None
    extra: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)
    ema_state: dict[str, torch.Tensor] | None = None
    meta: dict = field(default_factory=dict)
    train_state: dict | None = None
    code_version: str = __version__

    def build_model(self, ema: bool = True) -> nn.Module:
        """The kind's model with the EMA weights (if present and ``ema``) or the raw weights, in eval mode."""
        model = _spec(self.kind, "").build(self.model_config)
        state = self.ema_state if ema and self.ema_state is not None else self.model_state
        try:
            model.load_state_dict(state)
        except RuntimeError as e:
            raise ValueError(f"checkpoint weights do not match its model config ({str(e).splitlines()[0]}); "
                             f"the file is inconsistent - re-export or retrain it") from e
        return model.eval()

    def build_diffusion(self) -> GaussianDiffusion:
        if self.diffusion_config is None:
            raise ValueError(f"this {self.kind!r} checkpoint has no diffusion config (its model is not a diffusion model)")
        return GaussianDiffusion(self.diffusion_config)


@dataclass(frozen=True)
class KindSpec:
    """How a checkpoint kind is built: ``config_from_dict`` (dict -> model config, unknown keys are
    errors), ``build`` (model config -> nn.Module), ``required`` (top-level payload keys beyond
    ``COMMON_KEYS``: "diffusion_config", "norm", "vocabulary", "fps", "L_epi", "k", "grid"),
    ``required_extra`` (keys of the payload's ``extra`` dict) and ``check`` (raises ValueError
    naming the inconsistency, for a loaded Checkpoint)."""

    config_from_dict: Callable[[dict], Any]
    build: Callable[[Any], nn.Module]
    required: tuple[str, ...] = ()
    required_extra: tuple[str, ...] = ()
    check: Callable[[Checkpoint], None] | None = None


# kind -> its KindSpec, or "module:attribute" of it (imported when first needed)
KINDS: dict[str, KindSpec | str] = {
    "generator": "trumans.model.checkpoint:GENERATOR_KIND",  # the TRUMANS denoiser
    "filter": "trumans.refine.filter:FILTER_KIND",  # the I'm-HOI filter
    "contact": "trumans.track.model_io:CONTACT_KIND",  # the iReplica contact predictor
    "motion_encoder": "trumans.eval.motion_encoder:MOTION_ENCODER_KIND",  # the evaluation network (FID, action acc)
}


def shipped_data_record(data: dict) -> dict:
    """A checkpoint's ``data`` record for a file that leaves this machine: each dataset's name and
    content hash, without the folder it was read from (a path of the training machine)."""
    out = {k: v for k, v in data.items() if k != "path"}
    if isinstance(out.get("augmented"), list):
        out["augmented"] = [shipped_data_record(a) if isinstance(a, dict) else a for a in out["augmented"]]
    return out


def register_kind(kind: CheckpointKind, spec: KindSpec) -> None:
    """Register (or replace) how checkpoints of ``kind`` are built and checked."""
    if kind not in get_args(CheckpointKind):
        raise ValueError(f"checkpoint kind must be one of {get_args(CheckpointKind)}, got {kind!r}")
    KINDS[kind] = spec


def _spec(kind: str, where: str) -> KindSpec:
    if kind not in get_args(CheckpointKind):
        raise ValueError(f"{where}unknown checkpoint kind {kind!r}; kinds are {get_args(CheckpointKind)}")
    if kind not in KINDS:
        raise ValueError(f"{where}no model builder is registered for {kind!r} checkpoints (registered: {sorted(KINDS)}); "
                         f"register one with trumans.model.checkpoint.register_kind")
    spec = KINDS[kind]
    if isinstance(spec, str):
        module, _, attr = spec.partition(":")
        spec = KINDS[kind] = getattr(importlib.import_module(module), attr)
    return spec


def _check_generator(ck: Checkpoint) -> None:
    cfg: DenoiserConfig = ck.model_config
    if ck.normalizer.mean.shape[0] != cfg.feature_dim:
        raise ValueError(f"normalisation has {ck.normalizer.mean.shape[0]} features but the model expects "
                         f"{cfg.feature_dim}; the checkpoint is inconsistent")
    if cfg.action is not None and cfg.action.num_actions != len(ck.vocabulary):
        raise ValueError(f"the action encoder takes {cfg.action.num_actions} actions but the vocabulary has "
                         f"{len(ck.vocabulary)}; the checkpoint is inconsistent")
    if cfg.frames != ck.L_epi:
        raise ValueError(f"the model takes {cfg.frames} frames but L_epi is {ck.L_epi}; the checkpoint is inconsistent")


GENERATOR_KIND = KindSpec(config_from_dict=DenoiserConfig.from_dict, build=Denoiser,
                          required=("diffusion_config", "norm", "vocabulary", "fps", "L_epi", "k", "grid"),
                          check=_check_generator)

# payload key -> (Checkpoint field, to plain data, from plain data)
_OPTIONAL: dict[str, tuple[str, Callable, Callable]] = {
    "diffusion_config": ("diffusion_config", lambda v: v.to_dict(), lambda v: DiffusionConfig(**v)),
    "norm": ("normalizer", lambda v: v.state_dict(), Normalizer.from_state_dict),
    "vocabulary": ("vocabulary", list, lambda v: [str(x) for x in v]),
    "fps": ("fps", float, float),
    "L_epi": ("L_epi", int, int),
    "k": ("k", int, int),
    "grid": ("grid", dict, dict),
}


def _payload_digest(payload: dict) -> str:
    """SHA-256 of a payload's content, independent of dict order and of how torch lays out the file."""
    h = hashlib.sha256()

    def walk(v) -> None:
        if isinstance(v, torch.Tensor):
            t = v.detach().cpu().contiguous().reshape(-1)
            h.update(f"T{t.dtype}{tuple(v.shape)}".encode())
            h.update(t.view(torch.uint8).numpy().tobytes())
        elif isinstance(v, dict):
            h.update(f"D{len(v)}".encode())
            for k in sorted(v, key=lambda k: (type(k).__name__, repr(k))):
                h.update(repr(k).encode())
                walk(v[k])
        elif isinstance(v, (list, tuple)):
            h.update(f"L{len(v)}".encode())
            for x in v:
                walk(x)
        else:
            h.update(f"V{type(v).__name__}:{v!r}".encode())

    walk({k: v for k, v in payload.items() if k != "digest"})
    return h.hexdigest()


def save_checkpoint(path: str | Path, ckpt: Checkpoint) -> None:
    """Write ``ckpt`` to ``path`` atomically (temp file, then rename); its kind's required fields must be set."""
    spec = _spec(ckpt.kind, "cannot save: ")
    payload = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "kind": ckpt.kind, "code_version": ckpt.code_version,
        "model_config": ckpt.model_config.to_dict(), "model": ckpt.model_state, "ema": ckpt.ema_state,
        "extra": dict(ckpt.extra), "data": dict(ckpt.data), "meta": dict(ckpt.meta), "train_state": ckpt.train_state,
    }
    for key, (name, to_plain, _) in _OPTIONAL.items():
        if getattr(ckpt, name) is not None:
            payload[key] = to_plain(getattr(ckpt, name))
    missing = [k for k in spec.required if k not in payload] + [f"extra.{k}" for k in spec.required_extra
                                                                 if k not in ckpt.extra]
    if missing:
        raise ValueError(f"cannot save a {ckpt.kind!r} checkpoint without {missing}")
    payload["digest"] = _payload_digest(payload)
    atomic_write(path, lambda tmp: torch.save(payload, tmp))


def load_checkpoint(path: str | Path, kind: CheckpointKind | None = "generator") -> Checkpoint:
    """Read a checkpoint (``weights_only=True``). ``kind``: the expected kind (None = any registered one).

    Raises FileNotFoundError for a missing file and ValueError, naming the problem and the fix,
    for a corrupt/foreign file, a newer format, a different or unregistered kind, missing fields
    or an inconsistent config.
    """
    path = check_input_file(path, "checkpoint", "train one with `trumans train --out RUN` (it writes "
                                                "RUN/checkpoint.pt)")
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
    if "digest" not in d:
        raise ValueError(f"{path} has no digest, so altered weights could not be told apart (a file written before "
                         f"checkpoints were signed, or edited since); if you trust it, sign it with "
                         f"`python -m trumans.model.checkpoint {path}`")
    if d["digest"] != _payload_digest(d):
        raise ValueError(f"{path} is not a readable trumans checkpoint (its content does not match the digest written "
                         f"with it); it is corrupt - use an intact copy or retrain")
    found = str(d.get("kind", "generator"))  # files from before kinds were typed are generators
    if kind is not None and found != kind:
        raise ValueError(f"{path} is a {found!r} checkpoint, but a {kind!r} checkpoint is needed here")
    spec = _spec(found, f"{path}: ")
    extra = d.get("extra") or {}
    missing = [k for k in COMMON_KEYS + spec.required if k not in d] + [f"extra.{k}" for k in spec.required_extra
                                                                         if k not in extra]
    if missing:
        raise ValueError(f"{path} lacks {missing}; the checkpoint is incomplete - retrain or re-export it")
    for part in ("model", "ema"):
        state = d.get(part) or {}
        bad = [k for k, v in state.items() if isinstance(v, torch.Tensor) and v.is_floating_point()
               and not bool(torch.isfinite(v).all())]
        if bad:
            raise ValueError(f"{path} has non-finite (NaN or inf) {part} weights in {bad[:3]}{' ...' if len(bad) > 3 else ''}; "
                             f"the run diverged - use an earlier checkpoint or retrain with a lower train.lr")
    try:
        fields = {name: from_plain(d[key]) for key, (name, _, from_plain) in _OPTIONAL.items() if d.get(key) is not None}
        model_config = spec.config_from_dict(d["model_config"])
    except (TypeError, ValueError, KeyError) as e:
        raise ValueError(f"{path} has an invalid model/diffusion config or normalisation ({e}); "
                         f"it was written by an incompatible version - retrain it") from e
    ck = Checkpoint(
        kind=found, model_config=model_config, model_state=d["model"], extra=dict(extra), data=dict(d.get("data") or {}),
        ema_state=d.get("ema"), meta=dict(d.get("meta") or {}), train_state=d.get("train_state"),
        code_version=str(d.get("code_version", "")), **fields)
    if spec.check is not None:
        try:
            spec.check(ck)
        except ValueError as e:
            raise ValueError(f"{path}: {e}") from e
    return ck


def resign_checkpoint(path: str | Path, out: str | Path | None = None) -> Path:
    """Write ``path``'s checkpoint with a digest of its current content to ``out`` (default: in place).
    For a file its owner trusts (one written before checkpoints were signed): the digest then vouches
    for exactly these bytes. The file is read without running code; its kind's checks run on load."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist")
    try:
        d = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # corrupt bytes surface as many types
        raise ValueError(f"{path} is not a readable trumans checkpoint ({type(e).__name__}); nothing to sign") from e
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"{path} is not a trumans checkpoint (no format={FORMAT!r}); nothing to sign")
    d["digest"] = _payload_digest(d)
    out = Path(out) if out is not None else path
    atomic_write(out, lambda tmp: torch.save(d, tmp))
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m trumans.model.checkpoint FILE [--out NEW]``: sign a trusted checkpoint (``resign_checkpoint``)."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m trumans.model.checkpoint",
                                description="sign a trusted checkpoint written before checkpoints carried a digest")
    p.add_argument("checkpoint")
    p.add_argument("--out", default=None, help="write the signed file here (default: in place)")
    a = p.parse_args(argv)
    try:
        print(resign_checkpoint(a.checkpoint, a.out))
    except (ValueError, OSError) as e:
        print(f"error: {e}")
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
