"""Contact-predictor checkpoints: the shared checkpoint format (``trumans.model.checkpoint``) with
kind "contact".

Payload: ``model_config`` (``ContactPredictorConfig.to_dict()``), ``model`` / ``ema`` (state
dicts), ``fps``, ``extra`` = {"classes", "hands"}, ``data`` ({"name", "hash", "path"}), ``meta``,
``train_state`` (None in an export); written atomically, read with ``torch.load(weights_only=True)``
(never executes code) and checked against its digest.
"""
from __future__ import annotations

from pathlib import Path

from torch import nn

from trumans import __version__
from trumans.model.checkpoint import Checkpoint, KindSpec, load_checkpoint, register_kind, save_checkpoint

from .predictor import CLASSES, HANDS, ContactPredictor, ContactPredictorConfig

__all__ = ["save_predictor", "load_predictor", "predictor_checkpoint", "DEFAULT_CHECKPOINT", "KIND"]

KIND = "contact"
# The shipped model (trained on the embedded synthetic dataset; see README "Interactions").
DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[2] / "models" / "contacts.pt"


def _check(ck: Checkpoint) -> None:
    if tuple(ck.extra.get("classes", ())) != CLASSES or tuple(ck.extra.get("hands", ())) != HANDS:
        raise ValueError(f"it predicts classes {ck.extra.get('classes')} / hands {ck.extra.get('hands')}, this code "
                         f"expects {list(CLASSES)} / {list(HANDS)}; retrain it")
    if abs(float(ck.fps) - ck.model_config.fps) > 1e-9:
        raise ValueError(f"its fps {ck.fps} differs from its model config's {ck.model_config.fps}; the checkpoint is inconsistent")


register_kind(KIND, KindSpec(config_from_dict=ContactPredictorConfig.from_dict, build=ContactPredictor,
                             required=("fps",), required_extra=("classes", "hands"), check=_check))


def predictor_checkpoint(model_config: ContactPredictorConfig, model_state: dict, *, ema_state: dict | None = None,
                         data: dict | None = None, meta: dict | None = None, train_state: dict | None = None) -> Checkpoint:
    """The Checkpoint of a contact predictor (weights as CPU state dicts)."""
    return Checkpoint(kind=KIND, model_config=model_config, model_state=model_state, ema_state=ema_state,
                      fps=float(model_config.fps), extra={"classes": list(CLASSES), "hands": list(HANDS)},
                      data=dict(data or {}), meta=dict(meta or {}), train_state=train_state, code_version=__version__)


def save_predictor(model: nn.Module, path: str | Path, data: dict | None = None, meta: dict | None = None) -> None:
    """Write ``model`` (a ContactPredictor) as an export (no training state) to ``path`` atomically."""
    state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
    save_checkpoint(path, predictor_checkpoint(model.config, state, data=data, meta=meta))


def load_predictor(path: str | Path | None = None) -> tuple[ContactPredictor, dict]:
    """Read a contact checkpoint (default: the shipped ``models/contacts.pt``) without executing
    code. Returns the model (EMA weights when present) in eval mode and a dict describing it
    (kind, model_config, fps, extra, data, meta)."""
    path = Path(path) if path is not None else DEFAULT_CHECKPOINT
    if not path.is_file():
        raise FileNotFoundError(f"contact checkpoint {path} does not exist; train one with "
                                f"`trumans train --task contact --data DATA --out RUN` or use the shipped models/contacts.pt")
    ck = load_checkpoint(path, kind=KIND)
    info = {"kind": ck.kind, "model_config": ck.model_config.to_dict(), "fps": ck.fps, "extra": ck.extra,
            "data": ck.data, "meta": ck.meta}
    return ck.build_model(), info
