"""Seated pelvis height targets for the sampler's guidance (``Goal.pelvis_z``).

The generator alone leaves a seated pelvis ~14 cm off its seat. The plan knows the seat: a
``sit`` phase carries ``info['seat_height']`` (``trumans.sample.controller.compile_plan``), so every new
frame of an episode in a sit phase gets the target pelvis height ``seat height + offset``, the
offset being the pelvis height above the seat surface of this body in the training data
(``trumans.sample.rollout.sit_offset``). The sampler's spatial guidance pulls the predicted body onto it.
"""
from __future__ import annotations

import numpy as np

__all__ = ["seated_heights", "SEATED_KINDS"]

SEATED_KINDS = ("sit",)  # phase kinds whose frames are seated (sit_down / stand_up move the pelvis)


def seated_heights(phase_of: np.ndarray, phases: list, offset: float, k: int) -> tuple[tuple[int, float], ...]:
    """phase_of: (L,) phase index per episode frame (-1 = none); phases: the compiled phases;
    offset: pelvis height above the seat, m; k: context frames (not targeted) ->
    ((frame, pelvis height m), ...) for the seated new frames."""
    out = []
    for f in np.flatnonzero(np.asarray(phase_of)[k:] >= 0) + k:
        p = phases[int(phase_of[f])]
        if p.kind in SEATED_KINDS and "seat_height" in p.info:
            out.append((int(f), float(p.info["seat_height"]) + offset))
    return tuple(out)
