"""What the training loop trains: the ``Task`` protocol and the task registry.

A task owns its model, data, loss, validation and checkpoint payload; the loop (``trumans.train.loop``)
owns everything they share: the optimiser, warm-up, EMA, clipping, DDP, exact resume, checkpoint
and validation cadence. ``trumans train --task NAME`` builds the task registered under NAME in ``TASKS``
(a lazily imported ``"module:factory"``): the generator, the HOI filter, the contact model and the
motion encoder (``trumans.train.tasks.<name>``); another component calls ``register_task``.

A factory is called as ``factory(config, overrides=..., ablate=...)``: config is a built-in
config name or TOML path (None = the task's default), overrides ``{section: {key: value}}``
(e.g. ``{"train": {"time_limit_s": 600}}``), ablate the task's ablation names (errors list them).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Protocol, Sequence

import torch
from torch import nn

from trumans.model.checkpoint import Checkpoint, CheckpointKind

__all__ = ["Task", "TaskLoss", "TaskFactory", "TASKS", "register_task", "make_task", "task_names"]


@dataclass
class TaskLoss:
    """loss: the scalar to minimise; terms: named scalar terms (logged in the run's history)."""

    loss: torch.Tensor
    terms: dict[str, torch.Tensor]


class Task(Protocol):
    """One trainable component. ``config`` has ``name``, ``train`` (``trumans.train.config.TrainSection``),
    ``to_dict()`` and the classmethod ``from_dict``; ``kind`` is the checkpoint kind it writes."""

    kind: CheckpointKind
    config: Any

    def setup(self, data_dir: str | Path, out_dir: Path, *, is_main: bool, barrier: Callable[[], None],
              prev: Checkpoint | None, seed: int = 0, extra_dirs: Sequence[str | Path] = (),
              progress: bool = True, fine_tune: bool = False) -> None:
        """Load (rank 0 first: it writes caches, then ``barrier()``, then the others) the training and
        validation data, batches ordered by ``seed``; with ``prev`` reuse its data statistics
        (normalisation) and refuse data it cannot read (another vocabulary or categories); a resumed run
        (``fine_tune`` False) also refuses data it was not trained on, while a fine-tuned one
        (``--init``, ``fine_tune`` True) may train on other data. The loop passes ``fine_tune`` only
        when fine-tuning, so a task without the keyword still trains and resumes."""

    def build_model(self) -> nn.Module:
        """A freshly initialised model (CPU); the loop seeds torch before calling it."""

    def batch(self, step: int, rank: int, world: int) -> Any:
        """This rank's part of global batch ``step``: a pure function of the seed and the arguments."""

    def loss(self, model: nn.Module, batch: Any, generator: torch.Generator, device: torch.device) -> TaskLoss:
        """The training loss of ``batch``; all randomness from ``generator`` (dropout: torch's global seed)."""

    def validate(self, model: nn.Module) -> tuple[float, float]:
        """(validation loss, the same loss of a trivial baseline) with fixed randomness (rank 0 only)."""

    def sizes(self) -> tuple[int, int]:
        """(training examples, validation examples)."""

    def checkpoint(self, *, model_state: dict, ema_state: dict, meta: dict, train_state: dict) -> Checkpoint:
        """The checkpoint of this task with the given weights and training state."""


TaskFactory = Callable[..., Task]

# name -> "module:attribute" (imported when first used) or a factory
TASKS: dict[str, str | TaskFactory] = {"generator": "trumans.train.tasks.generator:GeneratorTask.from_config",
                                      "filter": "trumans.train.tasks.filter:FilterTask.from_config",
                                      "contact": "trumans.train.tasks.contact:ContactTask.from_config",
                                      "motion_encoder": "trumans.train.tasks.motion_encoder:MotionEncoderTask.from_config"}


def register_task(name: str, factory: str | TaskFactory) -> None:
    """Register (or replace) the factory of task ``name``."""
    if not name or not name.replace("-", "").isalnum():
        raise ValueError(f"a task name is a word (letters, digits, '-'), got {name!r}")
    TASKS[name] = factory


def task_names() -> list[str]:
    return sorted(TASKS)


def _resolve(ref: str | TaskFactory) -> TaskFactory:
    if callable(ref):
        return ref
    module, _, attr = ref.partition(":")
    obj: Any = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def make_task(name: str, config: str | Path | None = None, *, overrides: dict[str, dict] | None = None,
              ablate: Sequence[str] = ()) -> Task:
    """The task registered as ``name`` built from ``config`` (None = its default) with ``overrides`` and ``ablate``."""
    if name not in TASKS:
        raise ValueError(f"unknown task {name!r}; registered tasks: {task_names()}")
    return _resolve(TASKS[name])(config, overrides=overrides or {}, ablate=list(ablate))
