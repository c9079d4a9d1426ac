"""``trumans scene inspect``: the seats, beds and tables a plan can name in a scene.

A mesh file (any format trimesh reads) is searched from its geometry and part names
(``trumans.scenes.affordances``), exactly as ``trumans sample --scene MESH`` does, so the names
printed are the ones ``--sit-on`` / ``--lie-on`` take. A scene folder lists its ``scene.json``
objects that carry a seat, a lying place or a surface (docs/generate.md "Seats, beds and tables").

One row per object: name, category, centre (x, y, z world m: the seat, else the lying place, else the
surface; a bed's lying place), height (m), facing (degrees from world +x: where a seated person faces; feet -> head for a
bed; the side a table is used from), how it was found. ``--json`` prints them as the last line.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

__all__ = ["add_arguments", "run", "inspect_scene"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("scene", metavar="MESH|FOLDER", help="a mesh file (.obj .ply .glb ...) or a scene folder")
    parser.add_argument("--up", choices=("z", "y"), default="z", help="up axis of a mesh file (as `trumans sample`)")
    parser.add_argument("--json", action="store_true", help="print the objects as JSON on the last line")


def inspect_scene(spec: str | Path, up: str = "z", notes: list[str] | None = None) -> list[dict]:
    """``describe`` rows of the seats, beds and tables of a mesh file or a scene folder. Raises
    FileNotFoundError / ValueError naming the problem (a missing path, an unreadable mesh, a mesh in
    centimetres or y-up read as z-up). Named parts that were skipped are explained in ``notes``."""
    from trumans.scenes.affordances import describe, mesh_affordances

    path = Path(spec)
    if path.is_dir():
        from trumans.scenes.io import load_scene

        if not (path / "scene.json").is_file():
            raise FileNotFoundError(f"{path} has no scene.json; give a scene folder written by trumans or a mesh file")
        objects = [o for o in load_scene(path).objects.values()
                   if any(k in o.meta for k in ("seat_center", "lie_center", "surface_center"))]
    elif path.is_file():
        from trumans.scenes.io import import_mesh

        objects = mesh_affordances(path, import_mesh(path, up=up), up=up, notes=notes)
    else:
        raise FileNotFoundError(f"{path} does not exist; give a mesh file (.obj .ply .glb ...) or a scene folder")
    return [describe(o) for o in objects]


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    notes: list[str] = []
    rows = inspect_scene(args.scene, up=args.up, notes=notes)
    seconds = time.perf_counter() - t0
    if not rows:
        print(f"{args.scene}: no seat, bed or table found (seats: flat tops 0.33-0.62 m high with 0.9 m free above "
              f"and free floor beside them; name parts chair*/sofa*/bed*/table* to mark them)")
    else:
        print(f"{'name':<16} {'category':<8} {'centre (m)':<22} {'height':>6} {'facing':>7}  found by")
        for r in rows:
            c = "-" if r["center"] is None else ", ".join(f"{v:.2f}" for v in r["center"])
            h = "-" if r["height"] is None else f"{r['height']:.2f}"
            print(f"{r['name']:<16} {r['category']:<8} {c:<22} {h:>6} {r['facing_deg']:>6.0f}°  {r['found_by']}")
    for n in notes:
        print(f"note: {n}")
    if args.json:
        from trumans.summary import print_summary

        print_summary({"scene": str(args.scene), "objects": rows, "notes": notes, "seconds": round(seconds, 3)})
    return 0
