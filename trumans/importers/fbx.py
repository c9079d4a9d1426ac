"""FBX animation: skeleton models, parent links, animation curves, and world joint positions per frame.

Reads what skeletal animation needs from ASCII FBX 6.x / 7.x and binary FBX (``fbx_nodes``):
``Model`` nodes (bones are kinds ``Limb`` / ``LimbNode``) with their ``Lcl Translation / Rotation /
Scaling``, ``PreRotation``, ``PostRotation``, ``RotationOffset / RotationPivot``, ``ScalingOffset /
ScalingPivot`` and ``RotationOrder``; parent links from ``Connections``; animation from 6.x
``Takes`` (``Channel: "T" | "R" | "S"`` -> ``"X" | "Y" | "Z"`` ``Key:`` lists, the first take) or 7.x
``AnimationCurveNode`` / ``AnimationCurve`` objects (the first ``AnimationStack``); FBX time in ticks
(``FBX_TICKS`` per second); ``GlobalSettings`` ``UpAxis`` / ``UpAxisSign`` / ``UnitScaleFactor``.

A node's local matrix is the FBX SDK's (FBX SDK "Computing transformation matrix"):
``T @ Roff @ Rp @ Rpre @ R @ inv(Rpost) @ inv(Rp) @ Soff @ Sp @ S @ inv(Sp)``, where ``R`` composes
the Euler angles in ``RotationOrder`` (0 XYZ = rotate about x first, i.e. ``Rz @ Ry @ Rx``) and
pre/post rotations are always XYZ. World = parent world @ local (the default inherit type).
Curves are evaluated piecewise linearly (constant keys hold); cubic keys are treated as linear
between keys, which is exact at the keys (mocap is keyed every frame).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trumans.rotations import Y_UP_TO_Z_UP
from scipy.spatial.transform import Rotation

from .fbx_curves import FBX_TICKS, curves_v6, curves_v7
from .fbx_nodes import FbxNode, read_fbx_nodes

__all__ = ["FBX_TICKS", "FbxModel", "FbxScene", "read_fbx", "up_axis_matrix"]

_ORDERS = ["xyz", "xzy", "yzx", "yxz", "zxy", "zyx", "xyz"]  # RotationOrder enum (6 = spheric, read as XYZ)
_VEC_PROPS = ("Lcl Translation", "Lcl Rotation", "Lcl Scaling", "PreRotation", "PostRotation", "RotationOffset",
              "RotationPivot", "ScalingOffset", "ScalingPivot")
_BONE_KINDS = ("Limb", "LimbNode")


@dataclass
class FbxModel:
    """One ``Model`` node: its name, kind ("Limb", "LimbNode", "Mesh", "Null", ...), static
    properties (each a (3,) vector, file units / degrees), rotation order, limb length (or None)
    and animation curves ``{(property, axis): (times_s (K,), values (K,), constant (K,) bool)}``."""

    name: str
    kind: str
    props: dict[str, np.ndarray]
    rotation_order: int = 0
    limb_length: float | None = None
    curves: dict[tuple[str, int], tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)
    parent: int = -1


@dataclass
class FbxScene:
    """The models of an FBX file (parents precede children), its version, up axis and unit."""

    models: list[FbxModel]
    version: int
    binary: bool
    up_axis: int = 1  # 0 x, 1 y, 2 z
    up_sign: int = 1
    unit_cm: float = 1.0  # UnitScaleFactor: centimetres per file unit

    @property
    def names(self) -> list[str]:
        return [m.name for m in self.models]

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"model {name!r} is not in the FBX; it has: {', '.join(self.names)}") from None

    def time_range(self) -> tuple[float, float]:
        """First and last key time (s) over all curves; (0, 0) for a file without animation."""
        ts = [c[0] for m in self.models for c in m.curves.values() if len(c[0])]
        if not ts:
            return 0.0, 0.0
        return float(min(t[0] for t in ts)), float(max(t[-1] for t in ts))

    def key_fps(self) -> float | None:
        """The keying rate (frames/s) of the densest curve, snapped to an integer within 0.1 %."""
        dts = [np.median(np.diff(c[0])) for m in self.models for c in m.curves.values() if len(c[0]) > 2]
        if not dts:
            return None
        f = 1.0 / float(min(dts))
        return float(round(f)) if abs(f - round(f)) < 1e-3 * f else f

    def local_matrices(self, times: np.ndarray) -> np.ndarray:
        """Local 4x4 matrices (T, M, 4, 4) of every model at ``times`` (s), file units."""
        times = np.asarray(times, np.float64)
        out = np.empty((len(times), len(self.models), 4, 4))
        for k, m in enumerate(self.models):
            vec = {p: np.broadcast_to(m.props[p], (len(times), 3)).copy() for p in _VEC_PROPS}
            for (prop, axis), (kt, kv, const) in m.curves.items():
                vec[prop][:, axis] = _evaluate_curve(kt, kv, const, times)
            out[:, k] = _local_matrix(vec, m.rotation_order)
        return out

    def world_matrices(self, times: np.ndarray) -> np.ndarray:
        """World 4x4 matrices (T, M, 4, 4) at ``times`` (s), file units and axes."""
        L = self.local_matrices(times)
        W = np.empty_like(L)
        for k, m in enumerate(self.models):  # parents precede children
            W[:, k] = L[:, k] if m.parent < 0 else W[:, m.parent] @ L[:, k]
        return W

    def bones(self) -> list[int]:
        """Indices of the skeleton models (kind Limb / LimbNode)."""
        return [k for k, m in enumerate(self.models) if m.kind in _BONE_KINDS]

    def bone_axis(self) -> np.ndarray:
        """The local axis bones point along (3,) unit: the mean direction of child offsets in their
        parent's frame, snapped to the nearest signed axis (Blender exports: +x)."""
        offs = [m.props["Lcl Translation"] for m in self.models
                if m.parent >= 0 and self.models[m.parent].kind in _BONE_KINDS and m.kind in _BONE_KINDS]
        offs = [o / np.linalg.norm(o) for o in offs if np.linalg.norm(o) > 1e-9]
        if not offs:
            return np.array([1.0, 0.0, 0.0])
        mean = np.mean(offs, axis=0)
        axis = np.zeros(3)
        i = int(np.argmax(np.abs(mean)))
        axis[i] = np.sign(mean[i]) or 1.0
        return axis


def _euler_matrix(deg: np.ndarray, order: int) -> np.ndarray:
    """(T, 3) Euler degrees (x, y, z components) -> (T, 3, 3) for an FBX RotationOrder."""
    seq = _ORDERS[order] if 0 <= order < len(_ORDERS) else "xyz"
    cols = ["xyz".index(a) for a in seq]
    return Rotation.from_euler(seq, deg[:, cols], degrees=True).as_matrix()


def _local_matrix(vec: dict[str, np.ndarray], order: int) -> np.ndarray:
    T = len(vec["Lcl Translation"])

    def trans(v: np.ndarray) -> np.ndarray:
        m = np.broadcast_to(np.eye(4), (T, 4, 4)).copy()
        m[:, :3, 3] = v
        return m

    def rot(r: np.ndarray) -> np.ndarray:
        m = np.broadcast_to(np.eye(4), (T, 4, 4)).copy()
        m[:, :3, :3] = r
        return m

    S = np.broadcast_to(np.eye(4), (T, 4, 4)).copy()
    S[:, [0, 1, 2], [0, 1, 2]] = vec["Lcl Scaling"]
    R = rot(_euler_matrix(vec["Lcl Rotation"], order))
    Rpre = rot(_euler_matrix(vec["PreRotation"], 0))
    Rpost_inv = rot(np.swapaxes(_euler_matrix(vec["PostRotation"], 0), -1, -2))
    Rp, Sp = vec["RotationPivot"], vec["ScalingPivot"]
    return (trans(vec["Lcl Translation"]) @ trans(vec["RotationOffset"]) @ trans(Rp) @ Rpre @ R @ Rpost_inv
            @ trans(-Rp) @ trans(vec["ScalingOffset"]) @ trans(Sp) @ S @ trans(-Sp))


def _evaluate_curve(kt: np.ndarray, kv: np.ndarray, const: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Piecewise-linear curve at times t; a constant key holds its value until the next key;
    outside the keys the end values hold."""
    if len(kt) == 1:
        return np.full(len(t), kv[0])
    out = np.interp(t, kt, kv)
    if const.any():
        i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, len(kt) - 1)
        hold = const[i] & (t < kt[-1])
        out[hold] = kv[i[hold]]
    return out


# ------------------------------------------------------------------------------------------ reading

def read_fbx(path: str | Path) -> FbxScene:
    """Read the models, hierarchy, animation and axis settings of an FBX file (any encoding)."""
    nodes, version, binary = read_fbx_nodes(path)
    top = {n.name: n for n in nodes}
    objects = top.get("Objects")
    if objects is None:
        raise ValueError(f"{path}: the FBX has no Objects section")
    v7 = version >= 7000
    models: list[FbxModel] = []
    key_of: dict = {}  # connection key (7.x id or 6.x "Model::name") -> model index
    for n in objects.find_all("Model"):
        if v7:
            oid, full, kind = n.props[0], n.props[1], (n.props[2] if len(n.props) > 2 else "")
        else:
            oid, full, kind = n.props[0], n.props[0], (n.props[1] if len(n.props) > 1 else "")
        name = full.split("::", 1)[1] if "::" in full else full
        props, order, limb = _model_props(n, v7)
        key_of[oid] = len(models)
        models.append(FbxModel(name=name, kind=str(kind), props=props, rotation_order=order, limb_length=limb))
    if not models:
        raise ValueError(f"{path}: the FBX holds no Model nodes (no skeleton or animation to read)")
    links = _connections(top.get("Connections"))
    for child, parent, _prop in links:
        if child in key_of and parent in key_of and _prop is None:
            models[key_of[child]].parent = key_of[parent]
    if v7:
        curves_v7(objects, links, key_of, models, _VEC_PROPS)
    else:
        curves_v6(top.get("Takes"), key_of, models)
    settings = top.get("GlobalSettings") or objects.find("GlobalSettings")
    gs = _settings(settings, v7) if settings is not None else {}
    models = _topological(models, path)
    return FbxScene(models=models, version=version, binary=binary, up_axis=int(gs.get("UpAxis", 1)),
                    up_sign=int(gs.get("UpAxisSign", 1)) or 1, unit_cm=float(gs.get("UnitScaleFactor", 1.0)))


def _props_node(n: FbxNode, v7: bool) -> list[FbxNode]:
    pn = n.find("Properties70" if v7 else "Properties60")
    return [] if pn is None else pn.find_all("P" if v7 else "Property")


def _prop_values(p: FbxNode, v7: bool) -> list:
    return p.props[4:] if v7 else p.props[3:]


def _model_props(n: FbxNode, v7: bool) -> tuple[dict[str, np.ndarray], int, float | None]:
    props = {p: np.zeros(3) for p in _VEC_PROPS}
    props["Lcl Scaling"] = np.ones(3)
    order, limb = 0, None
    for p in _props_node(n, v7):
        if not p.props:
            continue
        key, vals = p.props[0], _prop_values(p, v7)
        if key in props and len(vals) >= 3:
            props[key] = np.asarray(vals[:3], np.float64)
        elif key == "RotationOrder" and vals:
            order = int(vals[0])
        elif key == "LimbLength" and vals:
            limb = float(vals[0])
    return props, order, limb


def _settings(node: FbxNode, v7: bool) -> dict[str, float]:
    out = {}
    for p in _props_node(node, v7):
        vals = _prop_values(p, v7)
        if p.props and vals and not isinstance(vals[0], str):
            out[p.props[0]] = vals[0]
    return out


def _connections(node: FbxNode | None) -> list[tuple[object, object, str | None]]:
    """(child, parent, property or None) for every OO / OP connection."""
    if node is None:
        return []
    out = []
    for c in node.children:
        if c.name not in ("C", "Connect") or len(c.props) < 3:
            continue
        kind, child, parent = c.props[0], c.props[1], c.props[2]
        prop = c.props[3] if kind == "OP" and len(c.props) > 3 else None
        out.append((child, parent, prop))
    return out


def _topological(models: list[FbxModel], path) -> list[FbxModel]:
    order: list[int] = []
    state = [0] * len(models)

    def visit(k: int) -> None:
        if state[k] == 2:
            return
        if state[k] == 1:
            raise ValueError(f"{path}: the model hierarchy has a cycle through {models[k].name!r}")
        state[k] = 1
        if models[k].parent >= 0:
            visit(models[k].parent)
        state[k] = 2
        order.append(k)

    for k in range(len(models)):
        visit(k)
    new = {old: i for i, old in enumerate(order)}
    out = [models[k] for k in order]
    for m in out:
        m.parent = new[m.parent] if m.parent >= 0 else -1
    return out


def up_axis_matrix(up_axis: int, up_sign: int = 1) -> np.ndarray:
    """(3, 3) rotation taking file axes to ours (z up): y-up files use the project's one y-up turn
    ``(x, y, z) = (X, -Z, Y)`` (``trumans.rotations.Y_UP_TO_Z_UP``, as BVH and mesh import), x-up
    ``(Y, Z, X)``, z-up identity; a negative up sign turns the body half a turn about the x axis
    (det +1 throughout)."""
    if up_axis not in (0, 1, 2):
        raise ValueError(f"UpAxis must be 0, 1 or 2, got {up_axis}")
    C = Y_UP_TO_Z_UP.copy() if up_axis == 1 else np.eye(3)[{2: [0, 1, 2], 0: [1, 2, 0]}[up_axis]]
    if up_sign < 0:
        C = np.diag([1.0, -1.0, -1.0]) @ C
    return C


# ------------------------------------------------------------------------------------------- import

def joint_positions(scene: FbxScene, times: np.ndarray) -> tuple[list[str], np.ndarray]:
    """Bone names and world positions (T, B, 3) in metres, our axes (z up), at ``times`` (s).

    Leaf bones with a ``LimbLength`` add their end as a joint ``<bone>_end`` (along the bones'
    axis, ``FbxScene.bone_axis``)."""
    bones = scene.bones()
    if not bones:
        raise ValueError("the FBX has no skeleton: no Model of kind 'Limb' or 'LimbNode'; models: "
                         f"{', '.join(f'{m.name} ({m.kind})' for m in scene.models)}")
    W = scene.world_matrices(times)
    names = [scene.models[b].name for b in bones]
    P = [W[:, b, :3, 3] for b in bones]
    parents = {m.parent for m in scene.models}
    axis = scene.bone_axis()
    for b in bones:
        m = scene.models[b]
        if b not in parents and m.limb_length:
            names.append(f"{m.name}_end")
            P.append(W[:, b, :3, 3] + W[:, b, :3, :3] @ (axis * m.limb_length))
    C = up_axis_matrix(scene.up_axis, scene.up_sign)
    return names, np.stack(P, axis=1) @ C.T * (scene.unit_cm / 100.0)


def import_fbx(path: str | Path, joint_map: dict[str, str] | None = None, skeleton: str | None = "auto",
               fps: float | None = None, unit_scale: float | None = None, refine_steps: int = 30,
               feet_on_floor: bool = False):
    """Read the skeletal animation of an FBX file as a trumans Sequence (24 joints, m, z-up).

    The curves are sampled at the file's keying rate (24 for the CMU FBX library) from the first to
    the last key, then resampled to ``fps`` when given. joint_map / skeleton / feet_on_floor as in
    ``trumans.importers.bvh.import_bvh``; unit_scale: metres per file unit (default: from the file's
    UnitScaleFactor, centimetres per unit). Rotations are fitted (``trumans.ik.fit``)."""
    from .joint_maps import place_on_floor, retarget_joints, sequence_from_joints

    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    if unit_scale is not None and not (np.isfinite(unit_scale) and unit_scale > 0):
        raise ValueError(f"unit_scale must be a positive number of metres per file unit, got {unit_scale}")
    scene = read_fbx(path)
    t0, t1 = scene.time_range()
    key_fps = scene.key_fps()
    if key_fps is None:
        raise ValueError(f"{path}: the FBX holds no animation curves with more than two keys")
    n = int(round((t1 - t0) * key_fps)) + 1
    times = t0 + np.arange(n) / key_fps
    names, P = joint_positions(scene, times)
    if unit_scale is not None:
        P = P / (scene.unit_cm / 100.0) * unit_scale
    joints = retarget_joints(names, P, joint_map, skeleton)
    seq = sequence_from_joints(joints, key_fps, target_fps=fps, refine_steps=refine_steps)
    return place_on_floor(seq, feet_on_floor, source=str(path))
