"""`trumans view --html`: one self-contained HTML viewer (three.js, offline) for one or more sequences.

``write_html([seq_a, seq_b], "out/view.html", [scene_a, scene_b])`` writes a single file that opens
in any WebGL browser without a network: the vendored three.js modules (``vendor/three``, MIT,
see its README) are embedded as ``data:`` URLs in an import map, each sequence's ``.glb``
(``trumans.viz.glb.write_glb``: its scene, the animated rigid-limb body, its moved objects) as
base64, and the per-frame overlays as JSON:

- the pelvis path on the floor, coloured by the action running at each frame;
- the action labels on a shared timeline (the active actions per frame, from ``actions`` /
  ``action_names``: every action whose label is > 0; a new interval of the same action, whose
  progress restarts, starts a new segment);
- contacts (``contacts (T, 24) bool``): a red sphere on each joint in contact at the current frame;
- goals, when the sequence records them in ``extra["goals"]``: ``(K, 4) float``, rows
  ``(frame, x, y, z)`` in m, z-up world, the frame at which the goal is due, with optional
  ``extra["goal_joints"] (K,) str`` naming the joint that must reach it (default ``pelvis``).

Several sequences are placed side by side along +x (each in its own scene, ``GAP_M`` apart) and
played on one timeline (the longest sequence's length; a shorter one holds its last frame).

The page's state is machine readable, for tests and scripts: ``<pre id="status">`` holds JSON
(``ready``, ``t`` s, ``playing``, ``frames`` per sequence, ``actions``, ``contacts``,
``pelvis_px`` (the pelvis projected to canvas pixels), ``errors``) and the URL hash
``#t=1.5&paused&speed=2&size=640x360`` sets the time, pauses, sets the speed and fixes the canvas
size (CSS px; default: the window's).
"""
from __future__ import annotations

import base64
import json
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
import trimesh

from trumans.sequence import Sequence, atomic_write
from trumans.skeleton import JOINT_NAMES, NUM_JOINTS
from trumans.viz.export import skeleton_motion
from trumans.viz.glb import write_glb
from trumans.viz.render import SceneView

__all__ = ["GAP_M", "MARKER_CUBE_M", "THREE_MODULES", "ViewerSequence", "action_segments", "check_html_path", "three_import_map",
           "viewer_sequence", "write_html"]

VENDOR_DIR = Path(__file__).resolve().parent / "vendor" / "three"
PAGE_DIR = Path(__file__).resolve().parent / "viewer"
GAP_M = 1.0  # m between the bounding boxes of side-by-side sequences
MARKER_CUBE_M = 0.1  # m, edge of the cube drawn for a tracked object without a mesh
# import specifier -> vendored file (path inside the three npm package); "three/addons/" is examples/jsm/
THREE_MODULES: dict[str, str] = {
    "three": "build/three.module.min.js",
    "three/build/three.core.min.js": "build/three.core.min.js",
    "three/addons/loaders/GLTFLoader.js": "examples/jsm/loaders/GLTFLoader.js",
    "three/addons/utils/BufferGeometryUtils.js": "examples/jsm/utils/BufferGeometryUtils.js",
    "three/addons/utils/SkeletonUtils.js": "examples/jsm/utils/SkeletonUtils.js",
    "three/addons/controls/OrbitControls.js": "examples/jsm/controls/OrbitControls.js",
}
# `from './x.js'` / `import '../y.js'` in a module; a data: URL has no base to resolve them against
_RELATIVE_IMPORT = re.compile(r"""(\bfrom\s*|\bimport\s*)(["'])(\.\.?/[^"']+)\2""")
_NO_ACTION = ""


def _specifier(package_path: str) -> str:
    """The import-map name of a vendored file: ``build/x.js`` -> ``three/build/x.js``,
    ``examples/jsm/a/b.js`` -> ``three/addons/a/b.js``."""
    if package_path.startswith("examples/jsm/"):
        return "three/addons/" + package_path[len("examples/jsm/"):]
    return "three/" + package_path


def three_import_map(vendor_dir: Path = VENDOR_DIR) -> dict[str, str]:
    """``{"imports": {specifier: data: URL}}`` for every module of ``THREE_MODULES``, each module's
    relative imports rewritten to the import-map names. Raises FileNotFoundError for a missing
    vendored file and ValueError for a relative import of a file that is not vendored."""
    names = {path: spec for spec, path in THREE_MODULES.items() if spec != "three"}
    imports = {}
    for spec, path in THREE_MODULES.items():
        f = vendor_dir / path
        if not f.is_file():
            raise FileNotFoundError(f"vendored three.js file {f} is missing; re-vendor three.js as "
                                    f"{vendor_dir / 'README.md'} says")
        text = f.read_text(encoding="utf-8")

        def rewrite(m: re.Match, path: str = path) -> str:
            target = str(PurePosixPath(_normpath(str(PurePosixPath(path).parent / m.group(3)))))
            if target not in names:
                raise ValueError(f"vendored {path} imports {m.group(3)} ({target}), which is not vendored; copy it "
                                 f"from the npm package and add it to trumans.viz.html.THREE_MODULES")
            return f"{m.group(1)}{m.group(2)}{names[target]}{m.group(2)}"

        text = _RELATIVE_IMPORT.sub(rewrite, text)
        imports[spec] = "data:text/javascript;base64," + base64.b64encode(text.encode("utf-8")).decode("ascii")
    return {"imports": imports}


def _normpath(p: str) -> str:
    """'a/b/../c' -> 'a/c' (posix, no filesystem access)."""
    out: list[str] = []
    for part in p.split("/"):
        if part == "..":
            if not out:
                raise ValueError(f"import path {p} leaves the three.js package")
            out.pop()
        elif part not in ("", "."):
            out.append(part)
    return "/".join(out)


def action_segments(actions: np.ndarray | None, names: list[str]) -> list[tuple[int, int, str]]:
    """Runs of the active actions: ``[(start, end, label)]``, frames ``[start, end)`` covering all T.

    actions: (T, N_A) labels (0 off, 1 + progress on; ``trumans.actions``). label: the active
    names joined by '+', '' when none is active. A segment also ends where an active action's
    progress restarts (a new interval of the same action)."""
    if actions is None or len(names) == 0:
        return []
    a = np.asarray(actions, np.float64)
    if a.ndim != 2 or a.shape[1] != len(names):
        raise ValueError(f"actions must be (T, {len(names)}) to match action_names, got {a.shape}")
    on = a > 0
    labels = ["+".join(n for n, o in zip(names, row) if o) for row in on]
    segs: list[tuple[int, int, str]] = []
    start = 0
    for f in range(1, len(a) + 1):
        if f == len(a) or labels[f] != labels[f - 1] or bool((on[f] & on[f - 1] & (a[f] < a[f - 1])).any()):
            segs.append((start, f, labels[start]))
            start = f
    return segs


@dataclass
class ViewerSequence:
    """One sequence as the page needs it: the .glb bytes (scene + body + moved objects) and overlays.

    joints: (T, 24, 3) float32 m, z-up world (overlays: path, contacts); contacts: (T, 24) bool or None;
    segments: ``action_segments``; goals: (K, 4) float (frame, x, y, z) with goal_joints (K,);
    bounds: (2, 3) min / max corner of scene + motion, m, z-up world."""

    title: str
    fps: float
    glb: bytes
    joints: np.ndarray
    contacts: np.ndarray | None
    segments: list[tuple[int, int, str]]
    goals: np.ndarray
    goal_joints: list[str]
    bounds: np.ndarray
    scene: str


def _goals(seq: Sequence) -> tuple[np.ndarray, list[str]]:
    """(K, 4) goals and their joint names from ``seq.extra`` (module docstring), validated."""
    if "goals" not in seq.extra:
        return np.zeros((0, 4)), []
    g = np.asarray(seq.extra["goals"], np.float64)
    if g.ndim != 2 or g.shape[1] != 4 or not np.isfinite(g).all():
        raise ValueError(f"extra['goals'] must be finite (K, 4) rows (frame, x, y, z), got shape {g.shape}; "
                         f"fix or drop the key")
    joints = [str(s) for s in seq.extra.get("goal_joints", ["pelvis"] * len(g))]
    if len(joints) != len(g) or any(j not in JOINT_NAMES for j in joints):
        raise ValueError(f"extra['goal_joints'] must name one joint of {JOINT_NAMES[:3]}... per goal "
                         f"({len(g)}), got {joints[:5]}")
    return g, joints


def viewer_sequence(seq: Sequence, scene: SceneView | None, title: str = "") -> ViewerSequence:
    """Build the page's data for ``seq`` drawn in ``scene`` (static meshes; dynamic meshes posed
    by the sequence's ``objects/<name>/pose``, else at their scene pose ``scene.dynamic_pose``, else
    not drawn; an object the sequence tracks but the scene has no mesh for is a ``MARKER_CUBE_M``
    cube at its pose). The body's rotations come from ``trumans.viz.export.skeleton_motion``."""
    seq.validate()
    if seq.allow_missing and np.isnan(seq.joints).any():
        raise ValueError(f"sequence {title!r} has missing (NaN) joints; refine it first (`trumans refine`) "
                         f"and view the refined sequence")
    static: dict[str, trimesh.Trimesh] = {}
    objects: dict[str, tuple[trimesh.Trimesh, np.ndarray]] = {}
    if scene is not None:
        static = {f"static_{i}": m for i, m in enumerate(scene.static) if len(m.faces)}
        # an object this sequence does not move is part of its static scene
        static.update({name: m.copy().apply_transform(scene.dynamic_pose[name]) for name, m in scene.dynamic.items()
                       if name not in seq.objects and name in scene.dynamic_pose})
        objects = {name: (m, seq.objects[name].pose) for name, m in scene.dynamic.items() if name in seq.objects}
    for name, track in seq.objects.items():
        if not np.isfinite(track.pose).all():
            raise ValueError(f"sequence {title!r}: objects/{name}/pose has missing (NaN) or infinite entries; refine "
                             f"it first (`trumans refine`) and view the refined sequence")
        if name not in objects:  # tracked, but the scene has no mesh for it: a marker cube shows the track
            objects[name] = (trimesh.creation.box((MARKER_CUBE_M,) * 3), track.pose)
    rot, root, off = skeleton_motion(seq)
    with tempfile.TemporaryDirectory(prefix="trumans_html_") as tmp:
        glb = write_glb(Path(tmp) / "seq.glb", rot, root, off, seq.fps, static_meshes=static,
                        objects=objects).read_bytes()
    pts = [seq.joints.reshape(-1, 3)] + [m.bounds for m in static.values()]
    pts += [np.asarray(p)[..., :3, 3].reshape(-1, 3) for _, p in objects.values()]
    allp = np.concatenate(pts).astype(np.float64)
    bounds = np.stack([allp.min(0), allp.max(0)])
    goals, goal_joints = _goals(seq)
    return ViewerSequence(title=title, fps=float(seq.fps), glb=glb, joints=np.asarray(seq.joints, np.float32),
                          contacts=None if seq.contacts is None else np.asarray(seq.contacts, bool),
                          segments=action_segments(seq.actions, seq.action_names), goals=goals,
                          goal_joints=goal_joints, bounds=bounds, scene=str(seq.scene))


# action colours: none close to the body's blue (the page's tests find the body by its hue)
_PALETTE = ["#ff7f0e", "#2ca02c", "#d62728", "#8c564b", "#e377c2", "#bcbd22", "#17a589", "#7d3c98", "#f1c40f",
            "#a04000"]
_NO_ACTION_COLOR = "#b0b0b0"


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")


def _payload(views: list[ViewerSequence]) -> dict:
    """The page's JSON: sequences placed side by side along +x, one colour per action label."""
    labels = sorted({s[2] for v in views for s in v.segments if s[2] != _NO_ACTION})
    palette = {lab: _PALETTE[i % len(_PALETTE)] for i, lab in enumerate(labels)}
    palette[_NO_ACTION] = _NO_ACTION_COLOR
    out, x = [], 0.0
    for k, v in enumerate(views):
        dx = 0.0 if k == 0 else x - v.bounds[0, 0]
        x = v.bounds[1, 0] + dx + GAP_M
        T = len(v.joints)
        out.append({
            "title": v.title, "scene": v.scene, "fps": v.fps, "frames": T, "offset": [dx, 0.0, 0.0],
            "bounds": (v.bounds + [dx, 0.0, 0.0]).tolist(),
            "glb": base64.b64encode(v.glb).decode("ascii"),
            "joints": _b64(v.joints.astype("<f4")),
            "contacts": None if v.contacts is None else _b64(v.contacts.astype(np.uint8)),
            "segments": [[int(s), int(e), lab] for s, e, lab in v.segments],
            "goals": [[float(g[0]), float(g[1]), float(g[2]), float(g[3]), j] for g, j in zip(v.goals, v.goal_joints)],
        })
    duration = max((len(v.joints) - 1) / v.fps for v in views)
    return {"version": 1, "duration": duration, "palette": palette, "joint_names": list(JOINT_NAMES),
            "sequences": out}


def _script_json(obj: dict) -> str:
    """JSON safe inside a <script> element (no '</' can close it)."""
    return json.dumps(obj, separators=(",", ":")).replace("</", "<\\/")


def check_html_path(path: str | Path) -> Path:
    """``path`` as a Path when it names an .html file; else ValueError naming the fix."""
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"the viewer is an .html file; give a path ending in .html, got {path}")
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give the viewer's file name, e.g. {path / 'view.html'}")
    return path


def write_html(seqs: list[Sequence], path: str | Path, scenes: list[SceneView | None] | None = None,
               titles: list[str] | None = None) -> Path:
    """Write the self-contained viewer of ``seqs`` (side by side, one timeline) to ``path`` (.html,
    atomically). scenes: one ``SceneView`` (or None) per sequence; titles: one label per sequence
    (default ``seq0``, ``seq1``, ...). Returns the path."""
    path = check_html_path(path)
    if not seqs:
        raise ValueError("no sequence to view; give at least one sequence")
    scenes = [None] * len(seqs) if scenes is None else list(scenes)
    titles = [f"seq{k}" for k in range(len(seqs))] if titles is None else list(titles)
    if len(scenes) != len(seqs) or len(titles) != len(seqs):
        raise ValueError(f"got {len(seqs)} sequences, {len(scenes)} scenes and {len(titles)} titles; "
                         f"pass one scene (or None) and one title per sequence")
    views = [viewer_sequence(s, sc, t) for s, sc, t in zip(seqs, scenes, titles)]
    page = (PAGE_DIR / "page.html").read_text(encoding="utf-8")
    script = (PAGE_DIR / "viewer.js").read_text(encoding="utf-8")
    licence = (VENDOR_DIR / "LICENSE").read_text(encoding="utf-8")
    parts = {
        "@@TITLE@@": _html_escape(" | ".join(titles)),
        "@@IMPORTMAP@@": _script_json(three_import_map()),
        "@@DATA@@": _script_json(_payload(views)),
        "@@VIEWER@@": script.replace("</script", "<\\/script"),
        "@@THREE_LICENSE@@": licence.replace("--", "- -"),  # inside an HTML comment
    }
    html = re.sub("|".join(re.escape(k) for k in parts), lambda m: parts[m.group(0)], page)
    atomic_write(path, lambda tmp: Path(tmp).write_text(html, encoding="utf-8"))
    return path


def _html_escape(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
