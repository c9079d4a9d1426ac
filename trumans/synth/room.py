"""What a take needs to know about its room: walk maps for planning and checking walks, and the
contact geometry that measures how deep a motion goes into the scene."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.scene import Scene
from trumans.scenes.walkability import WalkMap, walkable_map

from trumans.contacts.rule import ContactScene, contact_rule
from trumans.skeleton import JOINT_NAMES, forward_kinematics
from .motion import Motion

__all__ = ["RoomContext"]


@dataclass
class RoomContext:
    """What a take needs to know about its room (built once per room).

    ``plans``: walk maps for path planning with decreasing clearance (tried in order);
    ``check``: a fine walk map with the minimum clearance the walking pelvis must keep (the gait
    rounds the planned corners, so a path is accepted only if the generated pelvis track stays on
    it); ``contacts``: the contact geometry of the scene."""

    scene: Scene
    plans: list[WalkMap]
    check: WalkMap
    contacts: ContactScene
    fps: float = 30.0

    def penetration(self, m: Motion, poses: dict[str, np.ndarray]) -> float:
        """Deepest body penetration (m, see ``trumans.contacts.rule.body_penetration``) of motion ``m``
        with the dynamic objects at ``poses`` (or where ``m`` moves them)."""
        return self.worst_penetration(m, poses)[0]

    def worst_penetration(self, m: Motion, poses: dict[str, np.ndarray]) -> tuple[float, str]:
        """(deepest body penetration (m), 'joint into object at frame t') of motion ``m``."""
        tracks = {n: (m.objects[n] if n in m.objects and np.isfinite(m.objects[n]).all() else p[None])
                  for n, p in poses.items()}
        joints, G = forward_kinematics(m.rot, m.root, m.offsets)
        res = self.contacts.query(joints, tracks)
        d = contact_rule(joints, res, global_rot=G).penetration
        t, j = np.unravel_index(int(d.argmax()), d.shape)
        return float(d[t, j]), f"{JOINT_NAMES[j]} into {res.names[res.mesh_index[t, j]]} at frame {t}/{len(d)}"

    @property
    def walk(self) -> WalkMap:
        """The most permissive planning map."""
        return self.plans[-1]

    @staticmethod
    def build(scene: Scene, occ: OccupancyGrid, fps: float = 30.0,
              radii: tuple[float, ...] = (0.4, 0.3, 0.22), check_radius: float = 0.15) -> "RoomContext":
        """Planning maps at body radii ``radii`` (m), coarsened 2x (a coarse cell is walkable when
        its 2x2 fine cells are) so that path planning stays fast; the check map at ``check_radius``."""
        plans = []
        for r in radii:
            wm = walkable_map(occ, body_radius=r)
            w = wm.walkable
            nx, ny = (w.shape[0] // 2) * 2, (w.shape[1] // 2) * 2
            coarse = w[:nx, :ny].reshape(nx // 2, 2, ny // 2, 2).all(axis=(1, 3))
            plans.append(WalkMap(coarse, wm.origin + 0.5 * wm.cell, 2 * wm.cell))
        return RoomContext(scene, plans, walkable_map(occ, body_radius=check_radius), ContactScene(scene), fps)
