"""`make demo`: the main job on the embedded default.

Until the long-motion sampler lands, the demo builds a small synthetic HSI dataset (procedural
rooms + motions with actions and contacts), prints its figures, and renders one sequence
(GIF + top-down PNG) so a person can look at it.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
from pathlib import Path

from trumans.cli import console_main as cli_main


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m trumans.viz.demo", description=__doc__)
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--hours", type=float, default=0.05, help="hours of synthetic motion (default 0.05)")
    p.add_argument("--rooms", type=int, default=4, help="number of procedural rooms (default 4)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    out = Path(args.out)
    data = out / "data"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = cli_main(["data", "synth", "--out", str(data), "--hours", str(args.hours), "--rooms", str(args.rooms),
                       "--seed", str(args.seed), "--json"])
    if rc != 0:
        print(buf.getvalue(), end="")
        return rc
    figures = json.loads(buf.getvalue().strip().splitlines()[-1])
    index = json.loads((data / "index.json").read_text())
    first = sorted(sum(index["splits"].values(), []))[0]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = cli_main(["view", str(data / first), "--out", str(out / Path(first).stem), "--json"])
    if rc != 0:
        return rc
    figures["rendered"] = json.loads(buf.getvalue().strip().splitlines()[-1])
    print(f"dataset: {data}  ({figures.get('sequences')} sequences, {figures.get('hours', 0):.3f} h)")
    print(f"rendered: {figures['rendered']}")
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
