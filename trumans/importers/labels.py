"""Action labels of imported motion, read from the motion itself, and the converters' T-pose frame.

Imported BVH/FBX files carry no action labels; a generator cannot be trained without them. ``motion_labels``
labels every frame with a body state (stand, walk, turn, sit_down, sit, stand_up, lie_down, lie, get_up;
``trumans.motion_labels.label_states``, the corpus labeller), and each state becomes the action of the same
name in the embedded dataset's vocabulary (``trumans.synth.vocab.SYNTH_ACTIONS``), with the progress
indicator of TRUMANS §3.2 (``trumans.actions.labels_from_intervals``). Hand actions (drink, pick up, ...)
cannot be told from the body alone and stay unlabelled.
"""
from __future__ import annotations

import numpy as np

from trumans.actions import SYNTH_ACTIONS, ActionInterval, labels_from_intervals
from trumans.intervals import run_bounds
from trumans.motion_labels import MOTION_STATES, label_states
from trumans.sequence import Sequence

__all__ = ["motion_labels", "label_sequence", "drop_tpose_frame", "drop_converter_tpose"]


def motion_labels(joints: np.ndarray, fps: float) -> np.ndarray:
    """joints (T, 24, 3) world m, z up, at ``fps`` -> (T, len(SYNTH_ACTIONS)) action labels (the dataset
    format: 0 off, 1 + progress while on), one body-state action per frame."""
    states = label_states(np.asarray(joints, np.float64), float(fps))
    intervals = [ActionInterval(name, int(s), int(e)) for k, name in enumerate(MOTION_STATES)
                 for s, e in zip(*run_bounds(states == k))]
    return labels_from_intervals(intervals, list(SYNTH_ACTIONS), len(states))


def label_sequence(seq: Sequence) -> Sequence:
    """``seq`` with ``actions`` / ``action_names`` from ``motion_labels`` (a sequence that has labels is
    returned as it is)."""
    if seq.actions is not None and seq.action_names:
        return seq
    seq.actions = motion_labels(seq.joints, seq.fps).astype(np.float32)
    seq.action_names = list(SYNTH_ACTIONS)
    return seq


def drop_tpose_frame(joints: np.ndarray) -> np.ndarray:
    """Drop frame 0 when it is the converters' synthetic T-pose (arms straight out at shoulder
    height: wrists > 1.2 m apart and within 10 cm of the shoulders' height)."""
    from trumans.skeleton import JOINT_INDEX as J

    f = joints[0]
    span = np.linalg.norm(f[J["left_wrist"]] - f[J["right_wrist"]])
    level = max(abs(f[J["left_wrist"], 2] - f[J["left_shoulder"], 2]),
                abs(f[J["right_wrist"], 2] - f[J["right_shoulder"], 2]))
    return joints[1:] if span > 1.2 and level < 0.10 else joints


def drop_converter_tpose(seq: Sequence) -> tuple[Sequence, bool]:
    """Drop frame 0 of every per-frame field when it is a converter's synthetic T-pose
    (``drop_tpose_frame``: cgspeed and Daz BVHs start with one). Returns the
    sequence and whether a frame was dropped."""
    if seq.num_frames < 2 or len(drop_tpose_frame(np.asarray(seq.joints))) == seq.num_frames:
        return seq, False
    T = seq.num_frames
    for name in ("joints", "rotations", "root_pos", "actions", "contacts"):
        value = getattr(seq, name, None)
        if value is not None and len(value) == T:
            setattr(seq, name, value[1:])
    for ob in seq.objects.values():
        for name in ("pose", "imu_rot", "imu_acc"):
            value = getattr(ob, name, None)
            if value is not None and len(value) == T:
                setattr(ob, name, value[1:])
    seq.validate()
    return seq, True
