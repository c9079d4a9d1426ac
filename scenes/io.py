"""Scene folders (``scene.json`` + mesh files) and mesh import with y-up -> z-up conversion.

Folder layout (DESIGN.md "Files / Scene")::

    scene.json          {"format": "trumans-scene", "version": 1, "name", "meta",
                         "static": [{"name", "mesh"}],
                         "objects": [{"name", "category", "mesh", "pose" 4x4, "dof",
                                      "hinge_point" | null, "axis" | null, "dynamic", "meta"}]}
    static/<name>.ply   static meshes, world frame
    objects/<name>.ply  object meshes, object frame
    occupancy.npz       cache written by scenes.occupancy.scene_occupancy (kept across saves)

Mesh paths in scene.json are relative to the folder; any format trimesh reads is accepted.
Vertices are stored as float32 (binary PLY); poses, hinge points and axes as float64 JSON.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh

from .occupancy import OCCUPANCY_FILE
from .scene import DOFS, Scene, SceneObject

__all__ = ["save_scene", "load_scene", "import_mesh", "SCENE_FILE", "Y_UP_TO_Z_UP"]

SCENE_FILE = "scene.json"
FORMAT, VERSION = "trumans-scene", 1

# y-up -> z-up: +90 deg about x, (x, y, z) -> (x, -z, y); det = +1 (a proper rotation).
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def import_mesh(path: str | Path, up: Literal["y", "z"] = "z", scale: float = 1.0) -> trimesh.Trimesh:
    """Load any mesh/scene file trimesh reads as one Trimesh (scene graphs flattened, transforms
    applied), scaled by ``scale`` and converted to z-up if ``up == 'y'``. Vertex order is kept."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"mesh file {path} does not exist")
    if up not in ("y", "z"):
        raise ValueError(f"up must be 'y' or 'z', got {up!r}")
    if not (scale > 0 and np.isfinite(scale)):
        raise ValueError(f"scale must be a positive finite factor, got {scale}")
    try:
        loaded = trimesh.load(path, process=False)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ValueError(f"cannot read mesh file {path}: {e}") from e
    if isinstance(loaded, trimesh.Scene):
        geoms = [g for g in loaded.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)] \
            if hasattr(loaded, "dump") else []
        mesh = trimesh.util.concatenate(geoms) if geoms else trimesh.Trimesh()
    elif isinstance(loaded, trimesh.Trimesh):
        mesh = loaded
    else:
        raise ValueError(f"{path} holds a {type(loaded).__name__}, not a triangle mesh")
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"mesh file {path} has no triangles")
    mesh = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64) * scale, np.asarray(mesh.faces), process=False)
    if up == "y":
        T = np.eye(4)
        T[:3, :3] = Y_UP_TO_Z_UP
        mesh.apply_transform(T)
    return mesh


def _safe(name: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]", "_", name).strip(".") or "mesh"
    return s[:80]


def _unique_file(folder: str, name: str, used: set[str]) -> str:
    base = f"{folder}/{_safe(name)}"
    rel, i = f"{base}.ply", 1
    while rel.lower() in used:
        rel, i = f"{base}_{i}.ply", i + 1
    used.add(rel.lower())
    return rel


def _jsonable(x):
    return None if x is None else np.asarray(x, dtype=np.float64).tolist()


def save_scene(scene: Scene, folder: str | Path) -> None:
    """Write ``scene`` to ``folder`` (scene.json + binary PLY meshes). Everything is written to a
    temporary sibling folder first and then swapped in, so readers never see a half-written
    scene. An existing ``occupancy.npz`` is carried over (its hash key decides if it is stale).
    Refuses to replace a non-empty folder that is not a scene folder."""
    folder = Path(folder)
    if folder.exists() and (not folder.is_dir() or (any(folder.iterdir()) and not (folder / SCENE_FILE).is_file())):
        raise ValueError(f"{folder} exists and is not a scene folder; choose an empty or new folder")
    for name, m in scene.static.items():
        if len(m.faces) == 0:
            raise ValueError(f"static mesh {name!r} is empty; give it at least one face")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.", suffix=".tmp"))
    try:
        used: set[str] = set()
        doc = {"format": FORMAT, "version": VERSION, "name": scene.name, "meta": scene.meta,
               "static": [], "objects": []}
        for name, m in scene.static.items():
            rel = _unique_file("static", name, used)
            _export(m, tmp / rel)
            doc["static"].append({"name": name, "mesh": rel})
        for name, o in scene.objects.items():
            rel = _unique_file("objects", name, used)
            _export(o.mesh, tmp / rel)
            doc["objects"].append({
                "name": name, "category": o.category, "mesh": rel, "pose": _jsonable(o.pose),
                "dof": o.dof, "hinge_point": _jsonable(o.hinge_point), "axis": _jsonable(o.axis),
                "dynamic": bool(o.dynamic), "meta": o.meta,
            })
        try:
            text = json.dumps(doc, indent=1, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise ValueError(f"scene {scene.name!r}: meta must be JSON-serialisable ({e})") from e
        (tmp / SCENE_FILE).write_text(text)
        if (folder / OCCUPANCY_FILE).is_file():
            shutil.copy2(folder / OCCUPANCY_FILE, tmp / OCCUPANCY_FILE)
        if folder.exists():
            old = folder.with_name(f".{folder.name}.old.{os.getpid()}")
            os.replace(folder, old)
            os.replace(tmp, folder)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _export(mesh: trimesh.Trimesh, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    # PLY stores float32 vertices (sub-micron error at room scale); poses stay float64 in JSON
    m = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces), process=False)
    path.write_bytes(m.export(file_type="ply", encoding="binary"))


def _field(entry: dict, key: str, where: str):
    if key not in entry:
        raise ValueError(f"{where}: missing field {key!r}")
    return entry[key]


def _load_mesh(folder: Path, rel: str, where: str) -> trimesh.Trimesh:
    path = folder / rel
    if not path.is_file():
        raise FileNotFoundError(f"{where}: mesh file {path} is missing")
    mesh = import_mesh(path)
    if len(mesh.faces) == 0:
        raise ValueError(f"{where}: mesh file {path} is empty")
    return mesh


def load_scene(folder: str | Path) -> Scene:
    """Read a scene folder written by ``save_scene`` (or by hand in the same format)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"scene folder {folder} does not exist")
    path = folder / SCENE_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing; a scene folder needs a {SCENE_FILE}")
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not valid JSON: {e}") from e
    if not isinstance(doc, dict) or doc.get("format", FORMAT) != FORMAT:
        raise ValueError(f"{path} is not a {FORMAT} file")
    if int(doc.get("version", VERSION)) > VERSION:
        raise ValueError(f"{path} has version {doc['version']}; this code reads up to {VERSION}")
    static = {}
    for i, e in enumerate(doc.get("static", [])):
        where = f"{path} static[{i}]"
        name = str(_field(e, "name", where))
        static[name] = _load_mesh(folder, _field(e, "mesh", where), f"{where} ({name})")
    objects = {}
    for i, e in enumerate(doc.get("objects", [])):
        where = f"{path} objects[{i}]"
        name = str(_field(e, "name", where))
        where = f"{where} ({name})"
        dof = e.get("dof", "static")
        if dof not in DOFS:
            raise ValueError(f"{where}: unknown dof {dof!r}; use one of {DOFS}")
        pose = np.asarray(e.get("pose", np.eye(4).tolist()), dtype=np.float64)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise ValueError(f"{where}: pose must be a finite 4x4 matrix, got shape {pose.shape}")
        for key in ("hinge_point", "axis"):
            v = e.get(key)
            if v is not None and np.asarray(v, dtype=np.float64).shape != (3,):
                raise ValueError(f"{where}: {key} must have 3 numbers, got {v}")
        objects[name] = SceneObject(
            name=name, category=str(e.get("category", "")), mesh=_load_mesh(folder, _field(e, "mesh", where), where),
            pose=pose, dof=dof, hinge_point=e.get("hinge_point"), axis=e.get("axis"),
            dynamic=bool(e.get("dynamic", False)), meta=dict(e.get("meta", {})),
        )
    return Scene(name=str(doc.get("name", folder.name)), static=static, objects=objects, meta=dict(doc.get("meta", {})))
