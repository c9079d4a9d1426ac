"""`trumans view SEQ.npz [OTHER.npz ...]`: animated GIF/MP4 + top-down PNG of sequences, or (``--html``) one
self-contained HTML viewer (``trumans.viz.html``)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from trumans.argtypes import positive_int
from trumans.sequence import load_sequence

from .render import render_animation, render_topdown
from .scene_view import sequence_scene_view
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_hidden_alias, out_help

VIEW_FORMATS = ("gif", "mp4", "png")



def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("seq", nargs="+", help="sequence .npz; several are shown side by side (e.g. original and augmented)")
    p.add_argument("--scene", help="scene folder, mesh file, 'default' or room:SEED (as for `trumans sample`); default: "
                                   "the scene the sequence records (a sampled npz) or, for a dataset sequence, the "
                                   "dataset index's scene folder")
    p.add_argument("--up", choices=("z", "y"), default=None,
                   help="up axis of a mesh file given as --scene (default: as recorded by `trumans sample`, else z)")
    p.add_argument("--out", help=out_help("stem", "writes STEM.gif / STEM.mp4 and STEM_top.png (default: the first "
                                               "sequence's path without .npz)"))
    p.add_argument("--formats", default=None, metavar="LIST",
                   help=f"comma-separated among {','.join(VIEW_FORMATS)}: the animation (gif or mp4) and the top-down "
                        f"picture (png) (default gif,png)")
    add_hidden_alias(p, "--format", "animation_format", choices=["gif", "mp4"])  # before issue 37: --format mp4 = mp4,png
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


def run(args: argparse.Namespace) -> int:
    from trumans.out_paths import check_out

    check_out(args.out, "stem")
    if args.html:
        from .html import check_html_path

        check_html_path(args.html)
        if args.out:
            raise ValueError(f"--html {args.html} writes only the viewer; drop --out {args.out} (the GIF/PNG prefix)")
    formats = view_formats(args.formats, getattr(args, "animation_format", None), args.no_animation)
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
        written = {}
        if "png" in formats:
            written["topdown"] = str(render_topdown(seqs[0], prefix.with_name(prefix.name + "_top.png"), scene))
    animation = [f for f in formats if f in ("gif", "mp4")]
    if animation and not args.html:
        stride = max(args.stride, int(np.ceil(min(s.num_frames for s in seqs) / args.max_frames)))
        anim = prefix.with_name(prefix.name + "." + animation[0])
        render_animation(seqs, anim, scenes, camera=args.camera, stride=stride, titles=[p.stem for p in paths])
        written["animation"] = str(anim)
    for k, v in written.items():
        print(f"{k}: {v}", file=sys.stderr)
    if args.json:
        print_summary(written)
    return 0


def view_formats(formats: str | None, old: str | None, no_animation: bool) -> list[str]:
    """The outputs of ``view`` from ``--formats`` (or the older ``--format gif|mp4``, which meant that
    animation plus the PNG) and ``--no-animation``: a list among ``VIEW_FORMATS``, at most one animation."""
    if formats is not None and old is not None:
        raise ValueError(f"give the outputs once: --formats {formats} (--format {old} is its older spelling)")
    chosen = [f.strip() for f in (formats or f"{old or 'gif'},png").split(",") if f.strip()]
    bad = [f for f in chosen if f not in VIEW_FORMATS]
    if bad or not chosen:
        raise ValueError(f"--formats {formats!r}: choose among {','.join(VIEW_FORMATS)} (e.g. mp4,png)")
    if "gif" in chosen and "mp4" in chosen:
        raise ValueError("--formats: give one animation, gif or mp4, not both")
    if no_animation:
        chosen = [f for f in chosen if f == "png"] or ["png"]
    return chosen
