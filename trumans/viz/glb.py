"""glTF 2.0 binary (``.glb``) export: scene meshes plus an animated rigid-limb body.

The body is one glTF node per joint of our skeleton, in the skeleton's hierarchy: node ``j`` has
translation ``offsets[j]`` (the rest offset in its parent's frame; the pelvis node's translation is
the animated root position) and the animated local rotation ``R_j``, so glTF's node transform
(``parent @ T @ R``) is exactly our FK (``trumans.skeleton.forward_kinematics``). Each joint node
carries a rigid mesh: one capsule (``trimesh.creation.capsule``) per bone to each of its children
(a sphere for the head). Animation: one sampler input (times ``t / fps`` s), LINEAR interpolation,
``translation`` for the pelvis and ``rotation`` (quaternion ``(x, y, z, w)``, sign-continuous over
time) for every joint; dynamic objects get ``translation`` + ``rotation`` channels from their
per-frame pose.

Axes: glTF is y-up. Every node lives under one root node ``world_z_up`` whose rotation turns our
z-up world into glTF's y-up frame, ``(x, y, z) -> (x, z, -y)`` (-90 deg about x); the mesh data
and the node transforms below it stay in our metres, z-up.

File layout (glTF 2.0 §"Binary glTF Layout"): 12-byte header (magic ``glTF``, version 2, total
length), a JSON chunk padded with spaces to 4 bytes, a BIN chunk padded with zeros.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from trumans.sequence import atomic_write
from trumans.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS, children, forward_kinematics

__all__ = ["write_glb", "Z_UP_TO_Y_UP", "BONE_RADIUS"]

# rotation of the root node, (x, y, z, w): -90 deg about x maps z-up (x, y, z) to y-up (x, z, -y)
Z_UP_TO_Y_UP: np.ndarray = Rotation.from_euler("x", -90.0, degrees=True).as_quat()
# capsule radius (m) of the bone ending at each joint (keyed by the child joint's name)
BONE_RADIUS: dict[str, float] = {
    "left_hip": 0.07, "right_hip": 0.07, "spine1": 0.09, "left_knee": 0.065, "right_knee": 0.065,
    "spine2": 0.1, "left_ankle": 0.05, "right_ankle": 0.05, "spine3": 0.1, "left_foot": 0.04,
    "right_foot": 0.04, "neck": 0.05, "left_collar": 0.05, "right_collar": 0.05, "head": 0.045,
    "left_shoulder": 0.05, "right_shoulder": 0.05, "left_elbow": 0.045, "right_elbow": 0.045,
    "left_wrist": 0.035, "right_wrist": 0.035, "left_index1": 0.03, "right_index1": 0.03,
}
_HEAD_RADIUS = 0.1  # m, sphere centred _HEAD_RADIUS * 0.8 above the head joint (head frame z)
_COLORS = {"body": [0.23, 0.49, 0.85, 1.0], "static": [0.75, 0.75, 0.75, 1.0], "dynamic": [0.9, 0.63, 0.24, 1.0]}
# glTF constants
_FLOAT, _UINT, _USHORT = 5126, 5125, 5123
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963


class _Glb:
    """Accumulates the glTF JSON and the binary buffer."""

    def __init__(self) -> None:
        self.bin = bytearray()
        self.gltf: dict = {"asset": {"version": "2.0", "generator": "trumans trumans.viz.glb"}, "scene": 0,
                           "scenes": [{"nodes": [0]}], "nodes": [], "meshes": [], "materials": [],
                           "accessors": [], "bufferViews": [], "buffers": []}
        self.material = {}
        for kind, rgba in _COLORS.items():
            self.material[kind] = len(self.gltf["materials"])
            self.gltf["materials"].append({"name": kind, "doubleSided": kind != "body", "pbrMetallicRoughness": {
                "baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.8}})

    def accessor(self, data: np.ndarray, kind: str, target: int | None = None, minmax: bool = False) -> int:
        """Append ``data`` ((N,) or (N, k), float32 or uint32) as a bufferView + accessor; returns its index."""
        ctype = {np.dtype(np.uint32): _UINT, np.dtype(np.uint16): _USHORT}.get(np.dtype(data.dtype), _FLOAT)
        data = np.ascontiguousarray(data, dtype={_UINT: np.uint32, _USHORT: np.uint16}.get(ctype, np.float32))
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": data.nbytes}
        if target is not None:
            view["target"] = target
        self.bin += data.tobytes()
        self.bin += b"\0" * (-len(self.bin) % 4)  # every bufferView starts 4-aligned (uint16 data may end off it)
        self.gltf["bufferViews"].append(view)
        acc = {"bufferView": len(self.gltf["bufferViews"]) - 1, "componentType": ctype, "count": int(len(data)),
               "type": kind}
        if minmax:
            flat = data.reshape(len(data), -1)
            acc["min"], acc["max"] = flat.min(0).tolist(), flat.max(0).tolist()
        self.gltf["accessors"].append(acc)
        return len(self.gltf["accessors"]) - 1

    def mesh(self, m: trimesh.Trimesh, name: str, material: str, joints: np.ndarray | None = None) -> int:
        """A one-primitive mesh (POSITION with min/max, NORMAL, uint32 indices; with ``joints`` (V,) the
        skin joint index of every vertex, weight 1: JOINTS_0 / WEIGHTS_0); returns its index."""
        attrs = {"POSITION": self.accessor(np.asarray(m.vertices, np.float32), "VEC3", _ARRAY_BUFFER, minmax=True),
                 "NORMAL": self.accessor(np.asarray(m.vertex_normals, np.float32), "VEC3", _ARRAY_BUFFER)}
        if joints is not None:
            J = np.zeros((len(joints), 4), np.uint16)
            J[:, 0] = joints
            W = np.zeros((len(joints), 4), np.float32)
            W[:, 0] = 1.0
            attrs["JOINTS_0"] = self.accessor(J, "VEC4", _ARRAY_BUFFER)
            attrs["WEIGHTS_0"] = self.accessor(W, "VEC4", _ARRAY_BUFFER)
        idx = self.accessor(np.asarray(m.faces, np.uint32).reshape(-1), "SCALAR", _ELEMENT_ARRAY_BUFFER)
        self.gltf["meshes"].append({"name": name, "primitives": [
            {"attributes": attrs, "indices": idx, "material": self.material[material]}]})
        return len(self.gltf["meshes"]) - 1

    def node(self, **fields) -> int:
        self.gltf["nodes"].append({k: v for k, v in fields.items() if v is not None})
        return len(self.gltf["nodes"]) - 1

    def to_bytes(self) -> bytes:
        self.gltf["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(self.gltf, separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        bn = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        total = 12 + 8 + len(js) + 8 + len(bn)
        return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(js), b"JSON") + js
                + struct.pack("<I4s", len(bn), b"BIN\0") + bn)


def _continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternion signs (T, ..., 4) so consecutive frames have a non-negative dot product."""
    s = np.sign((q[1:] * q[:-1]).sum(-1))
    s[s == 0] = 1.0
    flips = np.concatenate([np.ones_like(s[:1]), np.cumprod(s, axis=0)])
    return q * flips[..., None]


def _bone_mesh(j: int, offsets: np.ndarray) -> trimesh.Trimesh | None:
    """Joint j's rigid mesh in its own frame: a capsule along the rest offset to each child (+ head sphere)."""
    parts = []
    for c in children(j):
        off = offsets[c]
        length = float(np.linalg.norm(off))
        if length < 1e-6:
            continue
        cap = trimesh.creation.capsule(height=length, radius=BONE_RADIUS[JOINT_NAMES[c]], count=[10, 10])
        T = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], off / length)  # capsule axis z -> bone
        T[:3, 3] = off / 2
        cap.apply_transform(T)
        parts.append(cap)
    if JOINT_NAMES[j] == "head":
        parts.append(trimesh.creation.icosphere(subdivisions=2, radius=_HEAD_RADIUS).apply_translation(
            [0.0, 0.0, 0.8 * _HEAD_RADIUS]))
    return trimesh.util.concatenate(parts) if parts else None


def _bind_matrices(rot0: np.ndarray, root0: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(24, 4, 4): each joint node's world matrix in the glTF file at the pose rot0 (24, 3, 3), root0 (3,) m,
    i.e. the y-up root node's turn times our FK (z-up) global transform of the joint."""
    P, G = forward_kinematics(rot0, root0, offsets)
    M = np.tile(np.eye(4), (NUM_JOINTS, 1, 1))
    M[:, :3, :3], M[:, :3, 3] = G, P
    W = np.eye(4)
    W[:3, :3] = Rotation.from_quat(Z_UP_TO_Y_UP).as_matrix()
    return W @ M


def _split_pose(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(..., 4, 4) similarity transforms -> translation (..., 3), quaternion (..., 4) xyzw, scale (..., 3)."""
    A = np.asarray(pose, np.float64)[..., :3, :3]
    scale = np.linalg.norm(A, axis=-2)
    R = A / scale[..., None, :]
    U, _, Vt = np.linalg.svd(R)  # nearest rotation (poses in files are float32)
    R = U @ Vt
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(*R.shape[:-2], 4)
    return np.asarray(pose, np.float64)[..., :3, 3], q, scale


def write_glb(path: str | Path, rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, fps: float,
              static_meshes: dict[str, trimesh.Trimesh] | None = None,
              objects: dict[str, tuple[trimesh.Trimesh, np.ndarray]] | None = None) -> Path:
    """Write an animated body (+ scene) as a ``.glb`` (atomically). Returns the path.

    rot: (T, 24, 3, 3) local rotations; root: (T, 3) pelvis positions, m, z-up world; offsets:
    (24, 3) rest offsets (m) that ``rot`` goes with; fps: frames per second (> 0).
    static_meshes: name -> world-frame mesh; objects: name -> (object-frame mesh, pose (T, 4, 4)
    animated or (4, 4) fixed world-from-object)."""
    rot, root, offsets = (np.asarray(a, np.float64) for a in (rot, root, offsets))
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3) or len(rot) == 0:
        raise ValueError(f"rot must be (T, 24, 3, 3) with T >= 1, got {rot.shape}")
    T = len(rot)
    if root.shape != (T, 3):
        raise ValueError(f"root must be ({T}, 3), got {root.shape}")
    if offsets.shape != (NUM_JOINTS, 3):
        raise ValueError(f"offsets must be (24, 3), got {offsets.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps}")
    g = _Glb()
    world = g.node(name="world_z_up", rotation=Z_UP_TO_Y_UP.tolist(), children=[])
    for name, m in (static_meshes or {}).items():
        if len(m.faces):
            g.gltf["nodes"][world]["children"].append(g.node(name=name, mesh=g.mesh(m, name, "static")))
    samplers, channels = [], []
    # one shared input accessor: frame times in seconds (a single frame needs no animation)
    times = g.accessor(np.arange(T, dtype=np.float32) / np.float32(fps), "SCALAR", minmax=True) if T > 1 else None

    def animate(node: int, path_: str, values: np.ndarray) -> None:
        if times is None:
            return
        out = g.accessor(values.astype(np.float32), "VEC4" if path_ == "rotation" else "VEC3")
        samplers.append({"input": times, "output": out, "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path_}})

    for name, (m, pose) in (objects or {}).items():
        pose = np.asarray(pose, np.float64)
        if pose.shape not in ((4, 4), (T, 4, 4)):
            raise ValueError(f"object {name!r}: pose must be (4, 4) or ({T}, 4, 4), got {pose.shape}")
        t, q, s = _split_pose(pose)
        animated = pose.ndim == 3
        n = g.node(name=name, mesh=g.mesh(m, name, "dynamic"), translation=(t[0] if animated else t).tolist(),
                   rotation=(q[0] if animated else q).tolist(), scale=(s[0] if animated else s).tolist())
        g.gltf["nodes"][world]["children"].append(n)
        if animated:
            animate(n, "translation", t)
            animate(n, "rotation", _continuous(q))
    quats = _continuous(Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_quat().reshape(T, NUM_JOINTS, 4))
    joint_node: list[int] = []
    for j in range(NUM_JOINTS):  # parents precede children in our joint order
        n = g.node(name=JOINT_NAMES[j], translation=(root[0] if j == 0 else offsets[j]).tolist(),
                   rotation=quats[0, j].tolist())
        joint_node.append(n)
        parent = world if j == 0 else joint_node[PARENTS[j]]
        g.gltf["nodes"][parent].setdefault("children", []).append(n)
        if j == 0:
            animate(n, "translation", root)
        animate(n, "rotation", quats[:, j])
    # one skinned body (glTF 2.0 §3.7.3): every bone's capsule bound rigidly to its joint at the frame-0 pose
    bind = _bind_matrices(rot[0], root[0], offsets)  # (24, 4, 4) glTF world of each joint node at frame 0
    parts, owner = [], []
    for j in range(NUM_JOINTS):
        bones = _bone_mesh(j, offsets)
        if bones is not None:
            parts.append(bones.copy().apply_transform(bind[j]))
            owner.append(np.full(len(bones.vertices), j))
    body = trimesh.util.concatenate(parts)
    ibm = np.linalg.inv(bind).transpose(0, 2, 1).reshape(NUM_JOINTS, 16)  # column-major MAT4
    skin = {"name": "body_skeleton", "joints": joint_node, "skeleton": joint_node[0],
            "inverseBindMatrices": g.accessor(ibm.astype(np.float32), "MAT4")}
    g.gltf["skins"] = [skin]
    body_node = g.node(name="body", mesh=g.mesh(body, "body", "body", joints=np.concatenate(owner)), skin=0)
    g.gltf["scenes"][0]["nodes"].append(body_node)  # a skinned mesh's own node transform is unused: a root node
    if samplers:
        g.gltf["animations"] = [{"name": "motion", "samplers": samplers, "channels": channels}]
    data = g.to_bytes()
    path = Path(path)
    atomic_write(path, lambda tmp: Path(tmp).write_bytes(data))
    return path
