"""Action vocabulary of the embedded synthetic dataset (saved with the data; never assume its order)."""
from __future__ import annotations

SYNTH_ACTIONS: tuple[str, ...] = (
    "stand", "walk", "turn", "sit_down", "sit", "stand_up", "lie_down", "lie", "get_up",
    "reach", "grasp", "pick_up", "carry", "put_down", "drink", "phone_call", "type", "use_mouse",
    "open_door", "close_door", "open_drawer", "close_drawer", "push", "pull",
)
