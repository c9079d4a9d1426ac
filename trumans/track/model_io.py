"""Contact-predictor checkpoints: the shared checkpoint format (``trumans.model.checkpoint``) with
kind "contact".

Payload: ``model_config`` (``ContactPredictorConfig.to_dict()``), ``model`` / ``ema`` (state
dicts), ``fps``, ``extra`` = {"classes", "hands"} (+ "dof" for a
per-dof model, ``per_dof``), ``data`` ({"name", "hash", "path"}), ``meta``,
``train_state`` (None in an export); written atomically, read with ``torch.load(weights_only=True)``
(never executes code) and checked against its digest.
"""
from __future__ import annotations

from pathlib import Path

from torch import nn

from trumans.version import __version__
from trumans.model.checkpoint import Checkpoint, KindSpec, load_checkpoint, save_checkpoint

from trumans.track.per_dof import DOFS, check_dof
from trumans.track.predictor import CLASSES, HANDS, ContactPredictor, ContactPredictorConfig
from trumans.paths import MODELS_DIR

__all__ = ["save_predictor", "load_predictor", "load_contact_models", "predictor_checkpoint", "DEFAULT_CHECKPOINT",
           "KIND", "ContactModels"]

# One model with a class head, or one model per dof class {dof: model} (``per_dof``).
ContactModels = ContactPredictor | dict[str, ContactPredictor]

KIND = "contact"
# The shipped model (trained on the embedded synthetic dataset; see README "Interactions").
DEFAULT_CHECKPOINT = MODELS_DIR / "contacts.pt"


def _check(ck: Checkpoint) -> None:
    if tuple(ck.extra.get("classes", ())) != CLASSES or tuple(ck.extra.get("hands", ())) != HANDS:
        raise ValueError(f"it predicts classes {ck.extra.get('classes')} / hands {ck.extra.get('hands')}, this code "
                         f"expects {list(CLASSES)} / {list(HANDS)}; retrain it")
    if abs(float(ck.fps) - ck.model_config.fps) > 1e-9:
        raise ValueError(f"its fps {ck.fps} differs from its model config's {ck.model_config.fps}; the checkpoint is inconsistent")
    if ck.extra.get("dof", DOFS[0]) not in DOFS:
        raise ValueError(f"it is a per-dof model of unknown dof {ck.extra.get('dof')!r} (known: {list(DOFS)}); retrain it")


CONTACT_KIND = KindSpec(config_from_dict=ContactPredictorConfig.from_dict, build=ContactPredictor,
                        required=("fps",), required_extra=("classes", "hands"), check=_check)


def predictor_checkpoint(model_config: ContactPredictorConfig, model_state: dict, *, ema_state: dict | None = None,
                         data: dict | None = None, meta: dict | None = None, train_state: dict | None = None,
                         dof: str = "all") -> Checkpoint:
    """The Checkpoint of a contact predictor (weights as CPU state dicts); ``dof``: "all" (one model,
    class head) or the dof class a per-dof model detects contacts with."""
    extra = {"classes": list(CLASSES), "hands": list(HANDS)}
    if check_dof(dof) != "all":
        extra["dof"] = dof
    return Checkpoint(kind=KIND, model_config=model_config, model_state=model_state, ema_state=ema_state,
                      fps=float(model_config.fps), extra=extra,
                      data=dict(data or {}), meta=dict(meta or {}), train_state=train_state, code_version=__version__)


def save_predictor(model: nn.Module, path: str | Path, data: dict | None = None, meta: dict | None = None,
                   dof: str = "all") -> None:
    """Write ``model`` (a ContactPredictor; ``dof`` as in ``predictor_checkpoint``) as an export (no
    training state) to ``path`` atomically."""
    state = {k: v.detach().cpu().clone() for k, v in model.state_dict().items()}
    save_checkpoint(path, predictor_checkpoint(model.config, state, data=data, meta=meta, dof=dof))


def load_predictor(path: str | Path | None = None, device: str = "cpu") -> tuple[ContactPredictor, dict]:
    """Read a contact checkpoint (default: the shipped ``models/contacts.pt``) without executing
    code. Returns the model (EMA weights when present) in eval mode on ``device`` and a dict describing
    it (kind, model_config, fps, extra, data, meta)."""
    path = Path(path) if path is not None else DEFAULT_CHECKPOINT
    if not path.is_file():
        raise FileNotFoundError(f"contact checkpoint {path} does not exist; train one with "
                                f"`trumans train --task contact --data DATA --out RUN` or use the shipped models/contacts.pt")
    ck = load_checkpoint(path, kind=KIND)
    info = {"kind": ck.kind, "model_config": ck.model_config.to_dict(), "fps": ck.fps, "extra": ck.extra,
            "data": ck.data, "meta": ck.meta, "dof": ck.extra.get("dof", "all")}
    return ck.build_model().to(device), info


def load_contact_models(specs: list[str] | tuple[str, ...] | None = None, device: str = "cpu") -> ContactModels:
    """The contact model(s) of command-line ``specs``: none = the shipped model; one ``PATH`` = a
    model with a class head; ``DOF=PATH`` entries (DOF in slide | hinge | free, each at most once)
    = one per-dof model each (``per_dof``), the checkpoint's recorded dof checked against DOF. Every
    model is moved to ``device`` (``predict_contacts`` runs its windows there)."""
    specs = list(specs or [])
    if not specs:
        specs = [str(DEFAULT_CHECKPOINT)]
    if len(specs) == 1 and ("=" not in specs[0] or Path(specs[0]).is_file()):
        model, info = load_predictor(specs[0], device)
        if info["dof"] != "all":
            raise ValueError(f"contact checkpoint {specs[0]} is a per-dof model (dof {info['dof']!r}); pass it as "
                             f"{info['dof']}={specs[0]} (with the other dofs' models), not alone")
        return model
    models: dict[str, ContactPredictor] = {}
    for spec in specs:
        dof, sep, path = spec.partition("=")
        if not sep or not path:
            raise ValueError(f"contact checkpoint {spec!r}: with several checkpoints each must be DOF=PATH "
                             f"(DOF in {list(DOFS)}), e.g. slide=runs/dof_slide/checkpoint.pt")
        check_dof(dof, allow_all=False)
        if dof in models:
            raise ValueError(f"contact checkpoint for dof {dof!r} given twice ({spec!r}); give one per dof")
        model, info = load_predictor(path, device)
        if info["dof"] != dof:
            what = "a model with a class head (all dofs)" if info["dof"] == "all" else f"the per-dof model of {info['dof']!r}"
            raise ValueError(f"contact checkpoint {path} is {what}, not a {dof!r} model; train one with "
                             f"`trumans train --task contact --config {dof}`")
        models[dof] = model
    return models
