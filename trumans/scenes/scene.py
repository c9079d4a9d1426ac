"""Scene model: static meshes + interactable objects with degrees of freedom.

Units metres, z up, floor at z = 0. Meshes are stored in the object's local frame; ``pose`` is
the 4x4 world-from-object transform. Degrees of freedom (iReplica §4.3):
``static`` never moves; ``slide`` translates along ``axis`` (object frame; floor-sliding furniture
uses axis = None meaning any horizontal direction); ``hinge`` rotates about ``axis`` through
``hinge_point`` (object frame); ``free`` is a rigid body with 6 DoF.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import trimesh

__all__ = ["Dof", "SceneObject", "Scene"]

Dof = Literal["static", "slide", "hinge", "free"]
DOFS: tuple[str, ...] = ("static", "slide", "hinge", "free")
# meta['found_by'] of objects found in a mesh's static geometry (trumans.scenes.affordances): SceneObject.part_of_static
FOUND_IN_STATIC: tuple[str, ...] = ("geometry", "name")


@dataclass
class SceneObject:
    """An interactable object. mesh: local frame; pose: (4, 4) world-from-object.

    ``meta`` holds JSON-serialisable semantics written by the procedural generator or the user
    (e.g. ``seat_height`` in m, ``seat_center`` (3,) local, ``grasp_points``), never arrays of
    mesh data.
    """

    name: str
    category: str
    mesh: trimesh.Trimesh
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    dof: Dof = "static"
    hinge_point: np.ndarray | None = None  # (3,) object frame, m
    axis: np.ndarray | None = None  # (3,) unit, object frame: hinge axis or slide direction
    dynamic: bool = False
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.pose = np.asarray(self.pose, dtype=np.float64)
        if self.pose.shape != (4, 4):
            raise ValueError(f"object {self.name!r}: pose must be (4, 4), got {self.pose.shape}")
        if self.dof not in DOFS:
            raise ValueError(f"object {self.name!r}: dof must be one of {DOFS}, got {self.dof!r}")
        if self.dof == "hinge" and (self.hinge_point is None or self.axis is None):
            raise ValueError(f"object {self.name!r}: a hinge needs hinge_point and axis")
        if self.hinge_point is not None:
            self.hinge_point = np.asarray(self.hinge_point, dtype=np.float64).reshape(3)
        if self.axis is not None:
            a = np.asarray(self.axis, dtype=np.float64).reshape(3)
            self.axis = a / np.linalg.norm(a)
        if len(self.mesh.faces) == 0:
            raise ValueError(f"object {self.name!r}: mesh is empty; give it at least one face")

    @property
    def part_of_static(self) -> bool:
        """True for an object found in the scene's static mesh (``meta['found_by']`` 'geometry' or 'name':
        ``trumans.scenes.affordances``): its faces are the static mesh's own, so renderers and exports draw
        them once, with the static mesh, not again as the object."""
        return not self.dynamic and self.dof == "static" and self.meta.get("found_by") in FOUND_IN_STATIC

    def world_mesh(self, pose: np.ndarray | None = None) -> trimesh.Trimesh:
        """The mesh placed at ``pose`` (default: its own pose), as a new Trimesh in world frame."""
        m = self.mesh.copy()
        m.apply_transform(self.pose if pose is None else pose)
        return m


@dataclass
class Scene:
    """A room: named static meshes (world frame) and interactable objects."""

    name: str
    static: dict[str, trimesh.Trimesh] = field(default_factory=dict)
    objects: dict[str, SceneObject] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def world_meshes(self, include_dynamic: bool = True) -> list[trimesh.Trimesh]:
        """Every mesh in world coordinates (static first, then objects at their poses)."""
        out = list(self.static.values())
        out += [o.world_mesh() for o in self.objects.values() if include_dynamic or not o.dynamic]
        return out

    def combined_mesh(self, include_dynamic: bool = True) -> trimesh.Trimesh:
        """All meshes concatenated in world frame."""
        return trimesh.util.concatenate(self.world_meshes(include_dynamic))

    def bounds(self) -> np.ndarray:
        """(2, 3) axis-aligned world bounds of every mesh."""
        return self.combined_mesh().bounds

    def object(self, name: str) -> SceneObject:
        if name not in self.objects:
            raise KeyError(f"scene {self.name!r} has no object {name!r}; it has {sorted(self.objects)}")
        return self.objects[name]
