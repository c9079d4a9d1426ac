"""Motion as rotations + root translation on an actor's skeleton: what every synthetic primitive returns.

Joints always come from forward kinematics of these rotations, so bone lengths are exact.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trumans.actions import ActionInterval
from trumans.rotations import matrix_to_6d
from trumans.skeleton import NUM_JOINTS, forward_kinematics

__all__ = ["Motion", "concat_motions", "yaw_of"]


def yaw_of(R: np.ndarray) -> np.ndarray:
    """Heading (rad) of rotations (..., 3, 3) or poses (..., 4, 4): the angle of their x axis
    projected on the ground plane, from world +x towards +y (the inverse of ``yaw_matrix``)."""
    return np.arctan2(R[..., 1, 0], R[..., 0, 0])


@dataclass
class Motion:
    """rot: (T, 24, 3, 3) float64 local rotations; root: (T, 3) pelvis world position (m);
    offsets: (24, 3) the actor's rest offsets (m); fps in Hz.

    ``foot_contact`` (T, 2) bool marks planted left/right feet; ``actions`` are intervals in this
    motion's frame numbers; ``objects`` maps object name -> (T, 4, 4) world pose while this motion
    moves it; ``grasp`` maps a hand joint index -> (T,) bool frames where it holds/touches an object.
    """

    rot: np.ndarray
    root: np.ndarray
    offsets: np.ndarray
    fps: float = 30.0
    foot_contact: np.ndarray | None = None
    actions: list[ActionInterval] = field(default_factory=list)
    objects: dict[str, np.ndarray] = field(default_factory=dict)
    grasp: dict[int, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        T = self.rot.shape[0]
        if self.rot.shape != (T, NUM_JOINTS, 3, 3):
            raise ValueError(f"rot must be (T, 24, 3, 3), got {self.rot.shape}")
        if self.root.shape != (T, 3):
            raise ValueError(f"root must be ({T}, 3), got {self.root.shape}")
        if self.offsets.shape != (NUM_JOINTS, 3):
            raise ValueError(f"offsets must be (24, 3), got {self.offsets.shape}")
        if self.foot_contact is None:
            self.foot_contact = np.zeros((T, 2), dtype=bool)

    @property
    def num_frames(self) -> int:
        return int(self.rot.shape[0])

    def joints(self) -> np.ndarray:
        """(T, 24, 3) world joint positions by FK (m)."""
        return forward_kinematics(self.rot, self.root, self.offsets)[0]

    def global_rot(self) -> np.ndarray:
        """(T, 24, 3, 3) global joint rotations."""
        return forward_kinematics(self.rot, self.root, self.offsets)[1]

    def reversed(self, label: str) -> "Motion":
        """This motion played backwards, labelled ``label`` on every frame; object tracks and grasp
        flags are reversed with it."""
        return Motion(rot=self.rot[::-1].copy(), root=self.root[::-1].copy(), offsets=self.offsets, fps=self.fps,
                      foot_contact=self.foot_contact[::-1].copy(),
                      actions=[ActionInterval(label, 0, self.num_frames)],
                      objects={k: v[::-1].copy() for k, v in self.objects.items()},
                      grasp={k: v[::-1].copy() for k, v in self.grasp.items()})

    def rotations_6d(self) -> np.ndarray:
        """(T, 24, 6) float32 local 6D rotations (first two columns)."""
        return matrix_to_6d(self.rot).astype(np.float32)


def concat_motions(parts: list[Motion]) -> Motion:
    """Concatenate motions of one actor in time (action intervals, object poses and grasp flags
    are shifted/padded; objects missing from a part are held at their nearest known pose by the caller)."""
    if not parts:
        raise ValueError("concat_motions needs at least one motion")
    off = parts[0].offsets
    T_total = sum(p.num_frames for p in parts)
    actions: list[ActionInterval] = []
    grasp: dict[int, np.ndarray] = {}
    objects: dict[str, np.ndarray] = {}
    start = 0
    for p in parts:
        if not np.allclose(p.offsets, off):
            raise ValueError("concat_motions: all parts must share the actor's offsets")
        actions += [ActionInterval(a.name, a.start + start, a.end + start) for a in p.actions]
        for j, g in p.grasp.items():
            grasp.setdefault(j, np.zeros(T_total, dtype=bool))[start:start + p.num_frames] = g
        for name, pose in p.objects.items():
            objects.setdefault(name, np.full((T_total, 4, 4), np.nan))[start:start + p.num_frames] = pose
        start += p.num_frames
    return Motion(
        rot=np.concatenate([p.rot for p in parts]),
        root=np.concatenate([p.root for p in parts]),
        offsets=off,
        fps=parts[0].fps,
        foot_contact=np.concatenate([p.foot_contact for p in parts]),
        actions=actions,
        objects=objects,
        grasp=grasp,
    )
