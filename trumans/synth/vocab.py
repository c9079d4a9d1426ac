"""Action vocabulary of the embedded synthetic dataset (``trumans.actions.SYNTH_ACTIONS``, the one definition)."""
from __future__ import annotations

from trumans.actions import SYNTH_ACTIONS

__all__ = ["SYNTH_ACTIONS"]
