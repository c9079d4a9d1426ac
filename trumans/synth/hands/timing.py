"""Phase timing of the hand primitives: one registry of nominal phase durations for every primitive.

The phase durations are drawn from ``rng``, lengthened so that the palm's mean speed stays under
``HAND_SPEED`` (and the torso's lean is as slow), and fitted to the base's length: spare frames go
to the primitive's steady phase (``FLEX``: holding, sipping, typing, ...), a shortage compresses
every phase (``nominal_frames`` gives a natural base length; a base under half the need is an error).
"""
from __future__ import annotations

import numpy as np

from ..poses import ease

__all__ = ["PHASES", "FLEX", "HAND_SPEED", "nominal_frames", "phases", "ramp"]

# Nominal phase durations (s): primitive -> phase name -> (low, high), phases in time order.
PHASES: dict[str, dict[str, tuple[float, float]]] = {
    # small objects (hands.objects, hands.face)
    "reach_grasp": {"reach": (1.0, 1.4), "grasp": (0.8, 1.6), "release": (0.9, 1.2)},
    "pick_up": {"reach": (1.0, 1.4), "grasp": (0.25, 0.4), "pick_up": (0.9, 1.3), "carry": (0.3, 0.8)},
    "put_down": {"put_down": (0.9, 1.3), "release": (0.2, 0.35), "retract": (0.8, 1.1)},
    "drink": {"raise": (1.1, 1.5), "sip": (1.2, 2.5), "lower": (1.0, 1.4)},
    "phone_call": {"raise": (1.2, 1.6), "talk": (2.0, 5.0), "lower": (1.1, 1.5)},
    # desk work (hands.desk)
    "type": {"reach": (0.9, 1.2), "work": (3.0, 8.0), "retract": (0.8, 1.1)},
    "use_mouse": {"reach": (0.8, 1.1), "work": (3.0, 8.0), "retract": (0.7, 1.0)},
    # doors and drawers (hands.doors, hands.drawers)
    "open_door": {"reach": (0.9, 1.2), "grasp": (0.2, 0.3), "move": (1.3, 2.0), "release": (0.15, 0.25),
                  "retract": (0.8, 1.1)},
    "close_door": {"reach": (0.9, 1.2), "grasp": (0.2, 0.3), "move": (1.2, 1.8), "release": (0.15, 0.25),
                   "retract": (0.8, 1.1)},
    "open_drawer": {"reach": (1.3, 1.7), "grasp": (0.2, 0.3), "move": (1.2, 1.8), "release": (0.15, 0.25),
                    "retract": (1.2, 1.6)},
    "close_drawer": {"reach": (1.3, 1.7), "grasp": (0.15, 0.25), "move": (1.1, 1.6), "release": (0.1, 0.2),
                     "retract": (1.2, 1.6)},
}
# The phase that absorbs spare frames of the base, per primitive.
FLEX: dict[str, str] = {"reach_grasp": "grasp", "pick_up": "carry", "put_down": "release", "drink": "sip",
                        "phone_call": "talk", "type": "work", "use_mouse": "work", "open_door": "move",
                        "close_door": "move", "open_drawer": "move", "close_drawer": "move"}
HAND_SPEED = 0.65  # m/s, mean palm speed of a reach (eased: peak ~1.9x, 1.2 m/s)


def _spec(kind: str) -> dict[str, tuple[float, float]]:
    if kind not in PHASES:
        raise ValueError(f"unknown primitive {kind!r}; choose one of {sorted(PHASES)}")
    return PHASES[kind]


def nominal_frames(kind: str, rng: np.random.Generator, fps: float = 30.0) -> int:
    """A natural length (frames) of a base motion for primitive ``kind`` (a key of ``PHASES``:
    reach_grasp, pick_up, put_down, drink, phone_call, type, use_mouse, open_door, close_door,
    open_drawer, close_drawer)."""
    # 25 % slack: reaches far away take longer than the nominal phases (see ``phases``).
    return int(round(1.25 * sum(rng.uniform(*v) for v in _spec(kind).values()) * fps)) + 1


def phases(kind: str, T: int, rng: np.random.Generator, fps: float,
           moves: dict[str, float] | None = None) -> dict[str, tuple[int, int]]:
    """Phase name -> (first frame, last frame) covering 0..T-1. Durations are drawn from the
    nominal table, raised so that each phase in ``moves`` (phase -> palm path length, m) keeps the
    mean hand speed under ``HAND_SPEED``; spare frames go to the FLEX phase, a shortage compresses
    every phase (at most 2x, else ValueError)."""
    spec = _spec(kind)
    names = list(spec)
    dur = np.array([rng.uniform(*v) for v in spec.values()])
    for k, dist in (moves or {}).items():
        i = names.index(k)
        dur[i] = max(dur[i], 0.25 + float(dist) / HAND_SPEED)
    need = dur.sum() * fps
    if T - 1 < 0.5 * need or T - 1 < 2 * len(spec):
        raise ValueError(f"{kind}: the base motion has {T} frames, too short for its phases "
                         f"(about {int(need) + 1} frames natural, at least {int(0.5 * need) + 1}); "
                         f"make the base with nominal_frames({kind!r}, rng, fps) frames or more")
    if T - 1 > need:
        dur[names.index(FLEX[kind])] += (T - 1 - need) / fps
    edges = np.round(np.concatenate([[0.0], np.cumsum(dur)]) / dur.sum() * (T - 1)).astype(int)
    return {k: (int(edges[i]), int(edges[i + 1])) for i, k in enumerate(names)}


def ramp(T: int, a: int, b: int) -> np.ndarray:
    """(T,) eased 0 -> 1 from frame a to frame b (0 before, 1 after)."""
    t = np.arange(T, dtype=np.float64)
    return ease((t - a) / max(b - a, 1))
