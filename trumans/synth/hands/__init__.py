"""Procedural hand interactions, each overlaid on a base motion of the body (conventions in ``core``).

core: palm point, hand frame, arm placement; timing: the phase registry; lean: torso lean;
objects: reach / pick up / carry / put down small objects; face: drink, phone call; desk: type,
use a mouse; doors, drawers, push: furniture that hinges, slides out or slides on the floor
(clearance: keeping the body clear of it).
"""
from .core import (
    INDEX1, PALM_GAP, PLAN_FRAC, REACH_FRAC, SHOULDER, SIGN, WRIST, OutOfReach, Side, hand_frame,
    hand_transform, heading_frame, palm_points, place_arm, slerp_track,
)
from .desk import TYPE_HOVER, type_keyboard, use_mouse
from .doors import DoorStance, close_door, door_pose, door_stance, open_door
from .drawers import Stance, close_drawer, drawer_pose, drawer_stance, open_drawer
from .face import drink, phone_call
from .lean import choose_lean, lean_travel
from .objects import Hold, carry, carry_pose, grasp_target, hand_for, pick_up, put_down, reach_grasp
from .push import pull, push, push_handles, push_stance
from .timing import HAND_SPEED, PHASES, nominal_frames

__all__ = [
    "INDEX1", "PALM_GAP", "PLAN_FRAC", "REACH_FRAC", "SHOULDER", "SIGN", "WRIST", "OutOfReach", "Side", "hand_frame",
    "hand_transform", "heading_frame", "palm_points", "place_arm", "slerp_track",
    "TYPE_HOVER", "type_keyboard", "use_mouse",
    "DoorStance", "close_door", "door_pose", "door_stance", "open_door",
    "Stance", "close_drawer", "drawer_pose", "drawer_stance", "open_drawer",
    "drink", "phone_call", "choose_lean", "lean_travel",
    "Hold", "carry", "carry_pose", "grasp_target", "hand_for", "pick_up", "put_down", "reach_grasp",
    "pull", "push", "push_handles", "push_stance",
    "HAND_SPEED", "PHASES", "nominal_frames",
]
