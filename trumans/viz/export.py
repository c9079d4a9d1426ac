"""Write a generated (or any) sequence in the formats a person asks for.

``export(seq, "out/run", {"npz", "bvh", "gif", "png", "glb"}, scene)`` writes ``out/run.npz``
(``trumans.sequence.save_sequence``), ``out/run.bvh`` (``trumans.bvh.write_bvh``; rotations fitted
with ``trumans.ik.fit.fit_rotations`` when the sequence has none that reproduce its joints),
``out/run.gif`` / ``out/run.mp4`` and ``out/run_top.png`` (``trumans.viz.render``) and
``out/run.glb`` (``trumans.viz.glb.write_glb``: scene meshes + an animated rigid-limb body). Every file
is written atomically.
"""
from __future__ import annotations

import importlib.util
import logging
from pathlib import Path
from typing import Literal, get_args

import numpy as np

from trumans.scenes.io import load_scene
from trumans.scenes.scene import Scene
from trumans.bvh import write_bvh
from trumans.ik.fit import fit_error, fit_rotations
from trumans.rotations import sixd_to_matrix
from trumans.sequence import Sequence, save_sequence
from trumans.skeleton import NUM_JOINTS, forward_kinematics, rest_offsets
from trumans.viz.scene_view import load_scene_view, scene_view
from trumans.viz.render import SceneView, render_animation, render_topdown

from trumans.viz.glb import write_glb

__all__ = ["ExportFormat", "FORMATS", "export", "export_paths", "skeleton_motion"]

log = logging.getLogger(__name__)

ExportFormat = Literal["npz", "bvh", "gif", "mp4", "png", "glb"]
FORMATS: tuple[str, ...] = get_args(ExportFormat)
_SUFFIX = {"npz": ".npz", "bvh": ".bvh", "gif": ".gif", "mp4": ".mp4", "png": "_top.png", "glb": ".glb"}
ROTATION_TOLERANCE_M = 0.005  # stored rotations are used when their FK is within this of the joints


def skeleton_motion(seq: Sequence, refine_steps: int = 30) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local rotations (T, 24, 3, 3), root positions (T, 3) m and rest offsets (24, 3) m for ``seq``.

    The sequence's own ``rotations`` + ``root_pos`` (with ``extra["offsets"]``, else the rest
    offsets) are used when their FK reproduces ``joints`` within ``ROTATION_TOLERANCE_M``;
    otherwise rotations are fitted to the joints (``fit_rotations``, bone lengths from the data)."""
    if seq.rotations is not None and seq.root_pos is not None:
        off = np.asarray(seq.extra.get("offsets", rest_offsets()), np.float64)
        if off.shape == (NUM_JOINTS, 3):
            rot = sixd_to_matrix(np.asarray(seq.rotations, np.float64))
            root = np.asarray(seq.root_pos, np.float64)
            P, _ = forward_kinematics(rot, root, off)
            if np.abs(P - seq.joints).max() <= ROTATION_TOLERANCE_M:
                return rot, root, off
    rot, root, off = fit_rotations(seq.joints, refine_steps=refine_steps)
    err = fit_error(seq.joints, rot, root, off)
    log.info("export: rotations fitted to the joints (error mean %.1f mm, max %.1f mm)", 1e3 * err["mean"], 1e3 * err["max"])
    return rot, root, off


def export_paths(out: str | Path | dict[str, str | Path], formats: set[str] | str) -> dict[str, Path]:
    """Output path per format: from a stem (``out/run`` -> ``out/run.npz``, ``out/run_top.png``, ...)
    or an explicit {format: path}. Raises ValueError for unknown or missing formats."""
    formats = {formats} if isinstance(formats, str) else set(formats)
    unknown = sorted(set(formats) - set(FORMATS))
    if unknown:
        raise ValueError(f"unknown export format(s) {unknown}; choose from {list(FORMATS)}")
    if not formats:
        raise ValueError(f"no export format requested; choose from {list(FORMATS)}")
    if isinstance(out, dict):
        missing = sorted(set(formats) - set(out))
        if missing:
            raise ValueError(f"no output path given for format(s) {missing}; add them to the paths {dict(out)}")
        paths = {f: Path(out[f]) for f in formats}
        _check_suffixes(paths)
        return paths
    stem = Path(out)
    if stem.suffix.lstrip(".") in FORMATS:
        raise ValueError(f"pass the output stem without a format suffix (e.g. {stem.with_suffix('')}), got {stem}")
    return {f: stem.with_name(stem.name + _SUFFIX[f]) for f in formats}


def _check_suffixes(paths: dict[str, Path]) -> None:
    for f, p in paths.items():
        want = Path("x" + _SUFFIX[f]).suffix
        if p.suffix != want:
            raise ValueError(f"the {f} output must end in {want}, got {p}")


def _resolve_scene(scene: Scene | str | Path | None) -> tuple[Scene | None, SceneView | None]:
    """The scene and what the renderer draws of it (a folder also gives its cached occupancy grid)."""
    if scene is None:
        return None, None
    if isinstance(scene, Scene):
        return scene, scene_view(scene)
    if not isinstance(scene, (str, Path)):
        raise TypeError(f"scene must be a trumans.scenes.Scene, a scene folder or None, got {type(scene).__name__}")
    folder = Path(scene)
    if not (folder / "scene.json").is_file():
        raise FileNotFoundError(f"{folder} is not a scene folder (no scene.json); pass a scene folder, a "
                                "trumans.scenes.Scene or None")
    return load_scene(folder), load_scene_view(folder)


def _glb_scene(seq: Sequence, sc: Scene | None) -> tuple[dict, dict]:
    """(static meshes, objects) for write_glb: static meshes in world frame; every object in its own
    frame, at its per-frame pose where the sequence tracks it, else at its scene pose. Objects found in
    the static mesh (``SceneObject.part_of_static``: a raw mesh's seats, beds, tables) are not written
    again: their triangles are the static mesh's, each drawn once."""
    if sc is None:
        return {}, {}
    objects = {name: (o.mesh, seq.objects[name].pose if name in seq.objects else o.pose)
               for name, o in sc.objects.items() if not o.part_of_static}
    return dict(sc.static), objects


def export(seq: Sequence, out: str | Path | dict[str, str | Path], formats: set[ExportFormat] | set[str],
           scene: Scene | str | Path | None = None, stride: int | None = None,
           max_frames: int = 300) -> dict[str, Path]:
    """Write ``seq`` in ``formats`` (subset of ``FORMATS``) to the paths ``export_paths(out, formats)``.

    scene: a ``trumans.scenes.Scene``, a scene folder (meshes + cached occupancy for the top-down map) or
    None; stride: animation frame step (default: enough to keep at most ``max_frames`` frames).
    Returns {format: written path}."""
    from trumans.out_paths import refuse_dataset_file

    paths = export_paths(out, formats)
    for p in paths.values():
        refuse_dataset_file(p)
    seq.validate()
    if "mp4" in paths and importlib.util.find_spec("imageio_ffmpeg") is None:
        raise ValueError("mp4 export needs imageio's ffmpeg plugin (pip install 'imageio[ffmpeg]'); ask for gif instead")
    sc, view = _resolve_scene(scene)
    motion = skeleton_motion(seq) if {"bvh", "glb"} & set(paths) else None
    written: dict[str, Path] = {}
    for fmt in FORMATS:
        if fmt not in paths:
            continue
        p = paths[fmt]
        if fmt == "npz":
            save_sequence(seq, p)
        elif fmt == "bvh":
            write_bvh(p, *motion, seq.fps)
        elif fmt in ("gif", "mp4"):
            step = stride or max(1, int(np.ceil(seq.num_frames / max_frames)))
            render_animation([seq], p, view, stride=step)
        elif fmt == "png":
            render_topdown(seq, p, view)
        else:
            static, objects = _glb_scene(seq, sc)
            write_glb(p, *motion, seq.fps, static_meshes=static, objects=objects)
        written[fmt] = p
    return written
