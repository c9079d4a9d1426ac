"""One contact predictor per degree-of-freedom class (iReplica supp. §10.1).

The paper's contact predictor "comprises a set of transformers, one for each interaction class
[...] when one detects a starting contact, the object search in the neighbourhood is performed
only for the specific category". Each network therefore answers "is this hand in contact WITH AN
OBJECT OF MY CLASS": its positives are the frames where the hand is in contact and the frame's
interaction class (``labels.sequence_labels``) is its dof; every other frame of every window,
contacts with objects of another class (or the static scene) included, is a negative. (Dropping
or masking the other classes' windows instead would train a model that fires on any contact, and
the set would lose the robustness to the other classes' contacts that the paper builds it for.)

At inference the models run in parallel (``predict_dof_contacts``): a hand's contact probability
is the largest over the models, and each frame's class scores are the models' (both hands' max)
probabilities, so ``interactions.interval_classes`` gives each contact interval the class of the
model that fires most over it; "none" scores 0 (every interval comes from some dof's model).
The alternative, one model with a class head (``ContactPredictor.class_head``), is the default.
"""
from __future__ import annotations

from typing import Literal, Mapping, get_args

import numpy as np

from trumans.track.predictor import CLASSES, HANDS, ContactPredictor, predict_contacts

__all__ = ["ContactDof", "DOFS", "check_dof", "dof_hand_labels", "combine_dof_probabilities", "predict_dof_contacts"]

ContactDof = Literal["all", "slide", "hinge", "free"]  # "all" = one model for every class (+ class head)
DOFS: tuple[str, ...] = tuple(c for c in CLASSES if c != "none")  # the movable dof classes


def check_dof(dof: str, allow_all: bool = True) -> str:
    """``dof`` if it is a known dof class (or "all" when ``allow_all``), else ValueError."""
    known = list(get_args(ContactDof)) if allow_all else list(DOFS)
    if dof not in known:
        raise ValueError(f"unknown dof class {dof!r}; known: {known}")
    return dof


def dof_hand_labels(hands: np.ndarray, classes: np.ndarray, dof: str) -> np.ndarray:
    """Per-dof contact labels (module doc): hands (T, 2) bool/{0, 1} and classes (T,) int into
    CLASSES -> (T, 2) bool, a hand's contact kept only on frames whose class is ``dof``."""
    h = np.asarray(hands)
    c = np.asarray(classes)
    if h.ndim != 2 or h.shape[1] != len(HANDS) or c.shape != h.shape[:1]:
        raise ValueError(f"hands must be (T, 2) and classes (T,), got {h.shape} and {c.shape}")
    return (h > 0.5) & (c == CLASSES.index(check_dof(dof, allow_all=False)))[:, None]


def combine_dof_probabilities(probs: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-dof contact probabilities {dof: (T, 2)} -> contact (T, 2) = max over the models and
    class scores (T, len(CLASSES)): column dof = that model's max over the hands, "none" and the
    dofs without a model 0."""
    if not probs:
        raise ValueError("no per-dof contact probabilities; give at least one dof's model")
    shapes = {np.shape(p) for p in probs.values()}
    if len(shapes) != 1 or len(next(iter(shapes))) != 2 or next(iter(shapes))[1] != len(HANDS):
        raise ValueError(f"per-dof probabilities must all be (T, 2), got {sorted(shapes)}")
    stack = np.stack([np.asarray(probs[d], np.float32) for d in probs])  # (K, T, 2)
    scores = np.zeros((stack.shape[1], len(CLASSES)), np.float32)
    for k, d in enumerate(probs):  # K <= 3 models
        scores[:, CLASSES.index(check_dof(d, allow_all=False))] = stack[k].max(1)
    return stack.max(0), scores


def predict_dof_contacts(models: Mapping[str, ContactPredictor], rotations: np.ndarray,
                         stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``predict_contacts`` for a set of per-dof models {dof: model}: contact (T, 2) and class
    scores (T, len(CLASSES)) (``combine_dof_probabilities``)."""
    return combine_dof_probabilities({d: predict_contacts(m, rotations, stride=stride)[0] for d, m in models.items()})
