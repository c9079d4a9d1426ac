"""``trumans eval local-query``: time batched local occupancy queries on a room-sized grid.

Builds an ``--size`` room (default 8 m x 8 m x 2.5 m) with walls and random box furniture,
voxelises it at ``--voxel`` m with ``compute_occupancy``, then times ``local_grids`` on batches
of ``--batch`` random floor points and headings (median over ``--runs`` timed runs after one
warm-up). Reports the flat-floor case (all z_floor = 0, the usual one) and a mixed-height case.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import trimesh

from trumans.scenes.local_grid import local_grids
from trumans.scenes.occupancy import compute_occupancy
from trumans import argtypes


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (room layout and queries)")
    parser.add_argument("--batch", type=int, default=256, help="queries per batch")
    parser.add_argument("--runs", type=int, default=9, help="timed runs (median reported)")
    parser.add_argument("--n", type=int, default=32, help="local grid resolution per axis")
    parser.add_argument("--voxel", type=float, default=0.02, help="scene voxel size in m")
    parser.add_argument("--size", type=float, nargs=3, default=(8.0, 8.0, 2.5), metavar=("X", "Y", "Z"),
                        help="room size in m")
    parser.add_argument("--boxes", type=int, default=12, help="number of furniture boxes")
    parser.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def build_room(size: np.ndarray, n_boxes: int, rng: np.random.Generator) -> list[trimesh.Trimesh]:
    """Walls (0.1 m thick, inside [0, size]) plus ``n_boxes`` random boxes on the floor, world frame."""
    sx, sy, sz = size
    t = 0.1
    walls = [((sx, t, sz), (sx / 2, t / 2, sz / 2)), ((sx, t, sz), (sx / 2, sy - t / 2, sz / 2)),
             ((t, sy, sz), (t / 2, sy / 2, sz / 2)), ((t, sy, sz), (sx - t / 2, sy / 2, sz / 2))]
    meshes = []
    for ext, c in walls:
        m = trimesh.creation.box(ext)
        m.apply_translation(c)
        meshes.append(m)
    for _ in range(n_boxes):
        ext = rng.uniform([0.3, 0.3, 0.3], [1.5, 1.0, 1.2])
        m = trimesh.creation.box(ext, trimesh.transformations.rotation_matrix(rng.uniform(0, np.pi), [0, 0, 1]))
        m.apply_translation([rng.uniform(0.5, sx - 0.5), rng.uniform(0.5, sy - 0.5), ext[2] / 2])
        meshes.append(m)
    return meshes


def _time(fn, runs: int) -> float:
    fn()  # warm-up
    ts = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def run(args: argparse.Namespace) -> int:
    if args.batch < 1 or args.runs < 1 or args.n < 1 or args.voxel <= 0:
        raise ValueError("--batch, --runs, --n must be >= 1 and --voxel > 0")
    rng = np.random.default_rng(args.seed)
    size = np.asarray(args.size, dtype=np.float64)
    t0 = time.perf_counter()
    occ = compute_occupancy(build_room(size, args.boxes, rng), np.stack([np.zeros(3), size]), args.voxel)
    t_build = time.perf_counter() - t0
    print(f"room {size.tolist()} m at {args.voxel} m: grid {list(occ.shape)}, "
          f"{occ.grid.mean() * 100:.1f}% occupied, voxelised in {t_build:.2f} s")
    xy = rng.uniform([0, 0], size[:2], (args.batch, 2))
    yaw = rng.uniform(-np.pi, np.pi, args.batch)
    flat = np.c_[xy, np.zeros(args.batch)]
    mixed = np.c_[xy, rng.uniform(0.0, 0.8, args.batch)]
    t_flat = _time(lambda: local_grids(occ, flat, yaw, n=args.n), args.runs)
    t_mixed = _time(lambda: local_grids(occ, mixed, yaw, n=args.n), args.runs)
    for name, t in (("flat floor", t_flat), ("mixed floor heights", t_mixed)):
        print(f"{name}: {t * 1e3:.2f} ms per batch of {args.batch} ({args.n}^3 cells), "
              f"{args.batch / t:.0f} queries/s")
    if args.json:
        from trumans.summary import print_summary

        print_summary({
            "batch": args.batch, "n": args.n, "voxel": args.voxel, "grid": list(occ.shape),
            "ms_per_batch": round(t_flat * 1e3, 3), "queries_per_s": round(args.batch / t_flat, 1),
            "ms_per_batch_mixed_heights": round(t_mixed * 1e3, 3), "build_s": round(t_build, 3),
        })
    return 0


if __name__ == "__main__":
    import sys

    p = argparse.ArgumentParser(description=__doc__)
    add_arguments(p)
    sys.exit(run(p.parse_args()))
