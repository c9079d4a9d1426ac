"""The guidance terms in one table and their config.

``TERMS`` lists the terms in the order their costs are summed (goal, seat, penetration); each has
its config in ``GuidanceConfig`` under its name, with an ``enabled`` switch that ``trumans sample``
and ``trumans eval synthesis`` expose as ``--no-<flag>`` (generated from this table,
``trumans.sample.sampling_args``). The step size and the number of updates per denoising step are
the sampler's (``SamplerConfig.goal_guidance`` / ``goal_iters``; 0 = no guidance at all).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable

from trumans.sample.guidance.base import GuidanceInputs, GuidanceTerm
from trumans.sample.guidance.goal import GoalTerm, GoalTermConfig
from trumans.sample.guidance.penetration import PenetrationTerm, PenetrationTermConfig
from trumans.sample.guidance.seat import SeatTerm, SeatTermConfig

__all__ = ["TermSpec", "TERMS", "GuidanceConfig", "build_terms"]


@dataclass(frozen=True)
class TermSpec:
    """A guidance term: name (its ``GuidanceConfig`` field), flag (``--no-<flag>``), its config
    class, ``build(config, inputs) -> term or None``, and what it does (one line, for the help)."""

    name: str
    flag: str
    config: type
    build: Callable[[Any, GuidanceInputs], GuidanceTerm | None]
    does: str


TERMS: tuple[TermSpec, ...] = (
    TermSpec("goal", "goal-guidance", GoalTermConfig, GoalTerm.build,
             "pull the hips (and the hip line, for a goal heading) or the hand onto the episode goal; the other "
             "terms still act (--goal-guidance 0: no guidance at all) (guidance/goal.py)"),
    TermSpec("seat", "seat-guidance", SeatTermConfig, SeatTerm.build,
             "pull a seated pelvis to its seat's height (guidance/seat.py)"),
    TermSpec("penetration", "penetration-guidance", PenetrationTermConfig, PenetrationTerm.build,
             "push the predicted joints out of the scene (guidance/penetration.py)"),
)


@dataclass(frozen=True)
class GuidanceConfig:
    """One config per guidance term (``TERMS``), each with ``enabled``."""

    goal: GoalTermConfig = field(default_factory=GoalTermConfig)
    seat: SeatTermConfig = field(default_factory=SeatTermConfig)
    penetration: PenetrationTermConfig = field(default_factory=PenetrationTermConfig)

    def switched(self, **enabled: bool) -> GuidanceConfig:
        """A copy with the named terms switched on / off, e.g. ``switched(seat=False)``."""
        names = [s.name for s in TERMS]
        unknown = sorted(set(enabled) - set(names))
        if unknown:
            raise ValueError(f"unknown guidance terms {unknown}; the terms: {names}")
        return replace(self, **{k: replace(getattr(self, k), enabled=bool(v)) for k, v in enabled.items()})


def build_terms(config: GuidanceConfig, inputs: GuidanceInputs) -> list[GuidanceTerm]:
    """The enabled terms that have something to do in this episode, in ``TERMS`` order."""
    terms = [spec.build(getattr(config, spec.name), inputs) for spec in TERMS if getattr(config, spec.name).enabled]
    return [t for t in terms if t is not None]


assert [s.name for s in TERMS] == [f.name for f in fields(GuidanceConfig)], "TERMS and GuidanceConfig disagree"
