"""`trumans view SEQ.npz [OTHER.npz ...]`: animated GIF/MP4 + top-down PNG of sequences, or (``--html``) one
self-contained HTML viewer (``trumans.viz.html``)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from trumans.scenes.occupancy import OCCUPANCY_FILE, OccupancyGrid
from trumans.argtypes import positive_int
from trumans.dataset import INDEX_FILE, load_index
from trumans.scenes.spec import SCENE_UP_KEY, procedural_seed
from trumans.sequence import load_sequence

from .render import SceneView, render_animation, render_topdown
from trumans.summary import print_summary
from trumans import argtypes

if TYPE_CHECKING:
    from trumans.scenes.scene import Scene


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("seq", nargs="+", help="sequence .npz; several are shown side by side (e.g. original and augmented)")
    p.add_argument("--scene", help="scene folder, mesh file, 'default' or room:SEED (as for `trumans sample`); default: "
                                   "the scene the sequence records (a sampled npz) or, for a dataset sequence, the "
                                   "dataset index's scene folder")
    p.add_argument("--up", choices=("z", "y"), default=None,
                   help="up axis of a mesh file given as --scene (default: as recorded by `trumans sample`, else z)")
    p.add_argument("--out", help="output prefix (default: next to the first sequence)")
    p.add_argument("--format", choices=["gif", "mp4"], default="gif", help="animation format (default gif)")
    p.add_argument("--camera", choices=["fixed", "follow"], default="fixed", help="fixed camera or follow the body")
    p.add_argument("--stride", type=positive_int, default=3, help="render every N-th frame (default 3)")
    p.add_argument("--max-frames", type=positive_int, default=300, help="render at most this many frames (default 300)")
    p.add_argument("--no-animation", action="store_true", help="only write the top-down PNG")
    p.add_argument("--html", metavar="OUT.html",
                   help="write one self-contained HTML viewer instead of the GIF/MP4 and PNG (three.js embedded, opens "
                        "offline): orbit camera, play/pause/scrub, speed, action timeline, path, goals, contacts; "
                        "several sequences side by side on one timeline (docs/generate.md)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="unused (rendering is deterministic); accepted for uniformity")
    p.add_argument("--json", action="store_true", help="print the written paths as JSON on the last line")


def find_scene_dir(seq_path: Path, scene_field: str, explicit: str | None) -> Path | None:
    """The scene folder of a sequence: ``explicit``, else ``scene_field`` as a path, else the dataset
    index (``index.json`` beside or above the sequence) mapping scene ids to folders."""
    if explicit:
        d = Path(explicit)
        if not d.is_dir():
            raise FileNotFoundError(f"scene folder {d} does not exist")
        return d
    if scene_field and Path(scene_field).is_dir():
        return Path(scene_field)
    for root in (seq_path.parent, seq_path.parent.parent):
        if (root / INDEX_FILE).is_file() and scene_field:
            scenes = load_index(root)["scenes"]
            if scene_field in scenes and (root / scenes[scene_field]).is_dir():
                return root / scenes[scene_field]
    return None


def scene_view(sc: Scene) -> SceneView:
    """What the renderer draws of a ``trumans.scenes.Scene``: static meshes and non-dynamic objects in world
    frame, dynamic objects' meshes in their own frame (posed by the sequence) with their scene poses; no grid."""
    static = list(sc.static.values()) + [o.world_mesh() for o in sc.objects.values() if not o.dynamic]
    dynamic = {name: o.mesh for name, o in sc.objects.items() if o.dynamic}
    return SceneView(static=static, dynamic=dynamic, dynamic_pose={n: sc.objects[n].pose for n in dynamic})


def sequence_scene_view(seq_path: Path, seq, explicit: str | None, up: str | None) -> SceneView | None:
    """The scene to draw under a sequence: ``explicit`` (--scene) or the sequence's own ``scene`` field,
    each a scene folder, a mesh file, 'default' or 'room:SEED' (a relative path is tried from the current
    folder, then beside the sequence); a dataset sequence's scene id is looked up in the dataset index.
    ``up``: a mesh file's up axis (default: the sequence's recorded ``scene_up``, else z). None when
    the sequence names no scene that can be found (only ``explicit`` must exist)."""
    spec = explicit if explicit else (seq.scene or "")
    if not spec:
        return None
    seed = procedural_seed(spec)
    if seed is not None:
        from trumans.scenes.procedural import make_room

        return scene_view(make_room(seed))
    candidates = [Path(spec)] + ([] if explicit or Path(spec).is_absolute() else [seq_path.parent / spec])
    for path in candidates:
        if path.is_dir():
            return load_scene_view(path)
        if path.is_file():
            from trumans.scenes.io import import_mesh

            axis = up or (str(seq.extra[SCENE_UP_KEY]) if SCENE_UP_KEY in seq.extra else "z")
            return SceneView(static=[import_mesh(path, up=axis)], dynamic={})
    if explicit:
        raise FileNotFoundError(f"--scene {explicit}: no such scene folder or mesh file; give a scene folder, a mesh "
                                f"file, 'default' or room:SEED")
    return load_scene_view(find_scene_dir(seq_path, seq.scene, None))


def load_scene_view(folder: Path | None) -> SceneView | None:
    """Meshes from ``scene.json`` (when present) and the grid from ``occupancy.npz`` (when present)."""
    if folder is None:
        return None
    static, dynamic, poses = [], {}, {}
    if (folder / "scene.json").is_file():
        from trumans.scenes.io import load_scene

        view = scene_view(load_scene(folder))
        static, dynamic, poses = view.static, view.dynamic, view.dynamic_pose
    grid = origin = voxel = None
    if (folder / OCCUPANCY_FILE).is_file():
        occ = OccupancyGrid.load(folder / OCCUPANCY_FILE)
        grid, origin, voxel = occ.grid, occ.origin, occ.voxel
    return SceneView(static=static, dynamic=dynamic, grid=grid, origin=origin, voxel=voxel, dynamic_pose=poses)


def run(args: argparse.Namespace) -> int:
    if args.html:
        from .html import check_html_path

        check_html_path(args.html)
        if args.out:
            raise ValueError(f"--html {args.html} writes only the viewer; drop --out {args.out} (the GIF/PNG prefix)")
    paths = [Path(p) for p in args.seq]
    seqs = [load_sequence(p) for p in paths]
    # each sequence in its own scene (an augmented sequence lives in its changed scene)
    scenes = [sequence_scene_view(p, s, args.scene, args.up) for p, s in zip(paths, seqs)]
    scene = scenes[0]
    if args.html:
        from .html import write_html

        written = {"html": str(write_html(seqs, args.html, scenes, titles=[p.stem for p in paths]))}
    else:
        prefix = Path(args.out) if args.out else paths[0].with_suffix("")
        written = {"topdown": str(render_topdown(seqs[0], prefix.with_name(prefix.name + "_top.png"), scene))}
    if not args.no_animation and not args.html:
        stride = max(args.stride, int(np.ceil(min(s.num_frames for s in seqs) / args.max_frames)))
        anim = prefix.with_name(prefix.name + "." + args.format)
        render_animation(seqs, anim, scenes, camera=args.camera, stride=stride, titles=[p.stem for p in paths])
        written["animation"] = str(anim)
    for k, v in written.items():
        print(f"{k}: {v}", file=sys.stderr)
    if args.json:
        print_summary(written)
    return 0
