"""How fast procedural rooms are made (``trumans.scenes.procedural.make_room``): seconds per room.

    python benchmarks/procedural_rooms.py [--rooms N] [--first-seed S] [--json]

Makes ``--rooms`` rooms with consecutive seeds (one warm-up room first, not counted) and prints
the mean, median and slowest time per room. The synthetic-data builder makes one room per
scene, so this bounds its scene cost (the budget the old wall-clock test asserted: < 0.5 s).
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np

from trumans.scenes.procedural import make_room


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--rooms", type=int, default=10, help="rooms to make (default 10)")
    p.add_argument("--first-seed", type=int, default=100, help="seed of the first room (default 100)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    if args.rooms < 1:
        p.error(f"--rooms must be >= 1, got {args.rooms}")
    make_room(args.first_seed - 1)  # warm-up: imports, caches
    times = []
    for s in range(args.first_seed, args.first_seed + args.rooms):
        t = time.perf_counter()
        make_room(s)
        times.append(time.perf_counter() - t)
    out = {"rooms": args.rooms, "s_per_room_mean": float(np.mean(times)), "s_per_room_median": float(np.median(times)),
           "s_per_room_max": float(np.max(times))}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.rooms} rooms: {out['s_per_room_mean']:.3f} s/room mean, {out['s_per_room_median']:.3f} median, "
              f"{out['s_per_room_max']:.3f} max")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
