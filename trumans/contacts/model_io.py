"""Contact-predictor checkpoints (``.pt``, DESIGN.md "Files"; the generator's layout, kind "contact").

A plain dict written atomically with ``torch.save`` and read with ``torch.load(weights_only=True)``
(never executes code): ``format``, ``format_version``, ``kind`` = "contact", ``code_version``,
``model_config`` (``ContactPredictorConfig.to_dict()``), ``model`` (state dict), ``classes``,
``hands``, ``fps``, ``data`` ({"name", "hash"}), ``meta`` (training settings and figures).
"""
from __future__ import annotations

from pathlib import Path

import torch

from trumans import __version__
from trumans.sequence import atomic_write

from .predictor import CLASSES, HANDS, ContactPredictor, ContactPredictorConfig

__all__ = ["save_predictor", "load_predictor", "DEFAULT_CHECKPOINT", "KIND"]

KIND = "contact"
# The shipped model (trained on the embedded synthetic dataset; see README "Interactions").
DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[2] / "models" / "contacts.pt"


def save_predictor(model: ContactPredictor, path: str | Path, data: dict | None = None, meta: dict | None = None) -> None:
    """Write ``model`` (weights + config + class/hand names) to ``path`` atomically."""
    ckpt = {
        "format": "trumans-checkpoint", "format_version": 1, "kind": KIND, "code_version": __version__,
        "model_config": model.config.to_dict(),
        "model": {k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
        "classes": list(CLASSES), "hands": list(HANDS), "fps": float(model.config.fps),
        "data": dict(data or {}), "meta": dict(meta or {}),
    }
    atomic_write(path, lambda tmp: torch.save(ckpt, tmp))


def load_predictor(path: str | Path | None = None) -> tuple[ContactPredictor, dict]:
    """Read a contact checkpoint (default: the shipped ``models/contacts.pt``) without executing
    code. Returns the model in eval mode and the checkpoint dict (without the weights)."""
    path = Path(path) if path is not None else DEFAULT_CHECKPOINT
    if not path.is_file():
        raise FileNotFoundError(f"contact checkpoint {path} does not exist; train one with "
                                f"`trumans train --task contact` or use the shipped models/contacts.pt")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is reported the same way
        raise ValueError(f"{path} is not a readable checkpoint ({type(e).__name__}); re-create it "
                         f"(weights-only loading is required, unpickling code is refused)") from e
    if not isinstance(ckpt, dict) or ckpt.get("kind") != KIND:
        kind = ckpt.get("kind") if isinstance(ckpt, dict) else type(ckpt).__name__
        raise ValueError(f"{path} is not a contact-predictor checkpoint (kind {kind!r}, expected {KIND!r})")
    if tuple(ckpt.get("classes", ())) != CLASSES or tuple(ckpt.get("hands", ())) != HANDS:
        raise ValueError(f"{path} predicts classes {ckpt.get('classes')} / hands {ckpt.get('hands')}, "
                         f"this code expects {list(CLASSES)} / {list(HANDS)}; retrain it")
    model = ContactPredictor(ContactPredictorConfig.from_dict(ckpt["model_config"]))
    try:
        model.load_state_dict(ckpt["model"])
    except RuntimeError as e:
        raise ValueError(f"{path}: weights do not match its model config ({str(e).splitlines()[0]}); retrain it") from e
    model.eval()
    return model, {k: v for k, v in ckpt.items() if k != "model"}
