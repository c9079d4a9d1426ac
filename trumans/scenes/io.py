"""Scene folders (``scene.json`` + mesh files) and mesh import with y-up -> z-up conversion.

Folder layout (docs/conventions.md "File formats / Scene")::

    scene.json          {"format": "trumans-scene", "version": 1, "name", "meta",
                         "static": [{"name", "mesh"}],
                         "objects": [{"name", "category", "mesh", "pose" 4x4, "dof",
                                      "hinge_point" | null, "axis" | null, "dynamic", "meta"}]}
    static/<name>.ply   static meshes, world frame
    objects/<name>.ply  object meshes, object frame
    occupancy.npz       cache written by trumans.scenes.occupancy.scene_occupancy (kept across saves)

Mesh paths in scene.json are relative to the folder; any format trimesh reads is accepted.
Vertices are stored as float32 (binary PLY); poses, hinge points and axes as float64 JSON.
"""
from __future__ import annotations

import errno
import json
import os
import re
import shutil
import tempfile
from pathlib import Path
from typing import Literal

import numpy as np

from trumans.rotations import Y_UP_TO_Z_UP  # y-up (x, y, z) -> z-up (x, -z, y)
import trimesh

from trumans.scenes.occupancy import OCCUPANCY_FILE
from trumans.scenes.scene import DOFS, Scene, SceneObject
from trumans.scenes.atomic import umask_mode
from trumans.input_files import parse_json

__all__ = ["save_scene", "load_scene", "import_mesh", "scene_files", "SCENE_FILE", "Y_UP_TO_Z_UP"]

SCENE_FILE = "scene.json"
FORMAT, VERSION = "trumans-scene", 1



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


def _mesh_files(scene: Scene) -> tuple[list[str], list[str]]:
    """The relative mesh files ``save_scene`` writes for ``scene``: (static, objects), in scene order."""
    used: set[str] = set()
    static = [_unique_file("static", name, used) for name in scene.static]
    objects = [_unique_file("objects", name, used) for name in scene.objects]
    return static, objects


def scene_files(scene: Scene, occupancy: bool = True) -> list[str]:
    """Every file (relative to the scene folder) that ``save_scene(scene, folder)`` writes, plus
    ``occupancy.npz`` unless ``occupancy`` is False: what a dataset writer records as its outputs
    before writing them (``trumans.dataset.record_outputs``)."""
    static, objects = _mesh_files(scene)
    return [SCENE_FILE, *static, *objects] + ([OCCUPANCY_FILE] if occupancy else [])


def _jsonable(x):
    return None if x is None else np.asarray(x, dtype=np.float64).tolist()


def save_scene(scene: Scene, folder: str | Path) -> None:
    """Write ``scene`` to ``folder`` (scene.json + binary PLY meshes). Everything is written to a
    temporary sibling folder first and then swapped in, so readers never see a half-written
    scene. An existing ``occupancy.npz`` is carried over (its hash key decides if it is stale).
    Refuses to replace a non-empty folder that is not a scene folder."""
    folder = Path(folder)
    try:  # one listing: a concurrent saver may swap the folder between two separate checks
        entries = os.listdir(folder)
    except FileNotFoundError:
        entries = []
    except NotADirectoryError:
        entries = None
    if entries is None or (entries and SCENE_FILE not in entries):
        raise ValueError(f"{folder} exists and is not a scene folder; choose an empty or new folder")
    for name, m in scene.static.items():
        if len(m.faces) == 0:
            raise ValueError(f"static mesh {name!r} is empty; give it at least one face")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.", suffix=".tmp"))
    os.chmod(tmp, umask_mode(0o777))  # mkdtemp makes it private
    try:
        static_files, object_files = _mesh_files(scene)
        doc = {"format": FORMAT, "version": VERSION, "name": scene.name, "meta": scene.meta,
               "static": [], "objects": []}
        for (name, m), rel in zip(scene.static.items(), static_files):
            _export(m, tmp / rel)
            doc["static"].append({"name": name, "mesh": rel})
        for (name, o), rel in zip(scene.objects.items(), object_files):
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
        _swap_in(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _swap_in(tmp: Path, folder: Path) -> None:
    """Rename the finished folder ``tmp`` onto ``folder``, moving an existing one aside first.
    Concurrent savers of one folder race here (one's folder appears between another's two renames):
    each retries until its own rename lands, so every save completes and the last one wins."""
    for attempt in range(1000):
        old = tmp.with_name(f"{tmp.name[:-len('.tmp')]}.old{attempt}.tmp")  # swept as a temp if we die
        try:
            if folder.exists():
                os.replace(folder, old)
            os.replace(tmp, folder)
            return
        except FileNotFoundError:  # another saver moved ``folder`` away between our check and rename
            continue
        except OSError as e:
            if e.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                raise
            continue  # another saver's folder appeared between our two renames
        finally:
            _remove_scene_folder(old)
    raise OSError(f"could not replace {folder}: other processes keep saving it")


def _remove_scene_folder(folder: Path) -> None:
    """Delete a scene folder moved aside, its scene.json last: a concurrent saver that listed the
    folder just before it was moved aside reads a listing that shrinks while we delete, and must
    still see a scene folder (scene.json present) or an empty one, never a foreign one."""
    if folder.is_symlink():  # a link moved aside: remove the link, never what it points to
        folder.unlink()
        return
    try:
        entries = os.listdir(folder)
    except (FileNotFoundError, NotADirectoryError):
        return
    for name in entries:
        if name != SCENE_FILE:
            path = folder / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
    (folder / SCENE_FILE).unlink(missing_ok=True)
    shutil.rmtree(folder, ignore_errors=True)


def _export(mesh: trimesh.Trimesh, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    # PLY stores float32 vertices (sub-micron error at room scale); poses stay float64 in JSON
    m = trimesh.Trimesh(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces), process=False)
    path.write_bytes(m.export(file_type="ply", encoding="binary"))


def _field(entry: dict, key: str, where: str, kind: type | tuple[type, ...] = str, default=...):
    """entry[key], checked to be of ``kind`` (ValueError naming the field otherwise)."""
    if key not in entry or entry[key] is None:
        if default is ...:
            raise ValueError(f"{where}: missing field {key!r}; repair scene.json or re-save the scene")
        return default
    v = entry[key]
    if not isinstance(v, kind) or (isinstance(v, bool) and kind is not bool):
        want = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise ValueError(f"{where}: field {key!r} must be {want}, got {type(v).__name__} {str(v)[:40]!r}; "
                         f"repair scene.json or re-save the scene")
    return v


def _numbers(v, shape: tuple[int, ...], where: str, key: str) -> np.ndarray:
    """A finite float64 array of ``shape`` from JSON numbers."""
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"{where}: {key} must be {'x'.join(map(str, shape))} finite numbers, got {str(v)[:60]}; "
                         f"repair scene.json or re-save the scene")
    return a


def _entries(doc: dict, key: str, path: Path) -> list[dict]:
    v = doc.get(key, [])
    if not isinstance(v, list) or not all(isinstance(e, dict) for e in v):
        raise ValueError(f"{path}: {key!r} must be a list of objects, got {str(v)[:60]}; repair scene.json "
                         f"or re-save the scene")
    return v


def _load_mesh(folder: Path, rel: str, where: str) -> trimesh.Trimesh:
    """The mesh ``rel`` of a scene folder; a path that leaves the folder (absolute, ``..``, a link out)
    is refused before anything is read, and the message never says whether such a path exists."""
    path = folder / rel
    root = folder.resolve()
    if Path(rel).is_absolute() or not path.resolve().is_relative_to(root):
        raise ValueError(f"{where}: mesh path {rel!r} leaves the scene folder; scene.json mesh paths are relative "
                         f"to the folder and stay inside it (copy the mesh into the folder)")
    if not path.is_file():
        raise FileNotFoundError(f"{where}: mesh file {path} is missing")
    mesh = import_mesh(path)
    if len(mesh.faces) == 0:
        raise ValueError(f"{where}: mesh file {path} is empty")
    return mesh


def load_scene(folder: str | Path) -> Scene:
    """Read a scene folder written by ``save_scene`` (or by hand in the same format); every field's
    type is checked (ValueError naming the field and the fix)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"scene folder {folder} does not exist")
    path = folder / SCENE_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing; a scene folder needs a {SCENE_FILE}")
    try:
        doc = parse_json(path.read_text(), f"scene file {path}", "repair it or re-save the scene")
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path} is not valid JSON ({e}); repair it or re-save the scene") from e
    if not isinstance(doc, dict) or doc.get("format", FORMAT) != FORMAT:
        raise ValueError(f"{path} is not a {FORMAT} file")
    version = _field(doc, "version", str(path), int, VERSION)
    if version > VERSION:
        raise ValueError(f"{path} has version {version}; this code reads up to {VERSION}")
    static = {}
    for i, e in enumerate(_entries(doc, "static", path)):
        where = f"{path} static[{i}]"
        name = _field(e, "name", where)
        static[name] = _load_mesh(folder, _field(e, "mesh", where), f"{where} ({name})")
    objects = {}
    for i, e in enumerate(_entries(doc, "objects", path)):
        where = f"{path} objects[{i}]"
        name = _field(e, "name", where)
        where = f"{where} ({name})"
        dof = _field(e, "dof", where, str, "static")
        if dof not in DOFS:
            raise ValueError(f"{where}: unknown dof {dof!r}; use one of {DOFS}")
        pose = _numbers(_field(e, "pose", where, list, np.eye(4).tolist()), (4, 4), where, "pose")
        hinge = {k: (None if e.get(k) is None else _numbers(e[k], (3,), where, k)) for k in ("hinge_point", "axis")}
        objects[name] = SceneObject(
            name=name, category=_field(e, "category", where, str, ""),
            mesh=_load_mesh(folder, _field(e, "mesh", where), where),
            pose=pose, dof=dof, hinge_point=hinge["hinge_point"], axis=hinge["axis"],
            dynamic=_field(e, "dynamic", where, bool, False), meta=dict(_field(e, "meta", where, dict, {})),
        )
    return Scene(name=_field(doc, "name", str(path), str, folder.name), static=static, objects=objects,
                 meta=dict(_field(doc, "meta", str(path), dict, {})))
