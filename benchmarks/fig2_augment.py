"""The TRUMANS Fig. 2 case made by this project: a chair raised by 15 cm and a bed lowered by
15 cm, the captured sitting / lying motion recomputed so that its contacts hold (appendix B.5).

    python benchmarks/fig2_augment.py --out out/fig2 [--seed S] [--json]

Writes ``<out>/{chair,bed}_{original,augmented}.npz`` with their scene folders, a side-by-side
GIF per case, and ``<out>/fig2_augment.png`` (both cases at their middle contact frame, the
image the README shows). Prints the figures: pelvis height change on the seat / bed (target
+15 / -15 cm), contact error, foot slide, bone-length change.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from trumans.augment.core import augment_sequence
from trumans.synth.cases import make_case
from trumans.augment.variations import Variation
from trumans.scenes.io import save_scene
from trumans.sequence import save_sequence
from trumans.skeleton import JOINT_INDEX, bone_lengths
from trumans.viz.scene_view import load_scene_view
from trumans.viz.render import render_animation, render_still

_FEET = [JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"]]


def _case(kind: str, obj: str, height_key: str, dz: float, seed: int, out: Path) -> dict:
    seq, scene = make_case(kind, seed)
    o = scene.objects[obj]
    h = float(o.meta[height_key] if np.ndim(o.meta[height_key]) == 0 else o.meta[height_key][2])
    var = Variation(obj, "scale", scale=(1.0, 1.0, (h + dz) / h))  # about the bottom: the surface moves by dz
    res = augment_sequence(seq, scene, [var], new_scene_id=f"{scene.name}_{obj}{dz:+.2f}")
    name = "chair" if obj == "chair" else "bed"
    paths = {}
    for tag, s, sc in (("original", seq, scene), ("augmented", res.sequence, res.scene)):
        sdir = out / f"{name}_{tag}_scene"
        save_scene(sc, sdir)
        s.scene = str(sdir)
        paths[tag] = out / f"{name}_{tag}.npz"
        save_sequence(s, paths[tag])
    pel = JOINT_INDEX["pelvis"]
    touch = np.array([any(iv.obj == obj and iv.joint == pel and iv.start <= t < iv.end for iv in res.intervals)
                      for t in range(seq.num_frames)])
    mid = int(np.flatnonzero(touch)[len(np.flatnonzero(touch)) // 2])
    P0, P1 = seq.joints.astype(np.float64), res.sequence.joints.astype(np.float64)
    feet_on_floor = P0[:, _FEET, 2].min(1) < 0.12
    return {
        "case": f"{name} {dz * 100:+.0f} cm",
        "frame": mid,
        "pelvis_dz_cm": float((P1[mid, pel, 2] - P0[mid, pel, 2]) * 100),
        "contact_err_cm": res.report["contact_err_cm"],
        "unreachable_frames": res.report["unreachable_frames"],
        "foot_move_cm": float(np.linalg.norm(P1[feet_on_floor][:, _FEET] - P0[feet_on_floor][:, _FEET], axis=-1).max() * 100)
        if feet_on_floor.any() else 0.0,
        "bone_length_err_mm": float(np.abs(bone_lengths(P1) - bone_lengths(P0)).max() * 1000),
        "_seqs": (seq, res.sequence), "_scenes": (load_scene_view(out / f"{name}_original_scene"),
                                                   load_scene_view(out / f"{name}_augmented_scene")),
        "_paths": paths,
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="out/fig2", help="output folder (default out/fig2)")
    p.add_argument("--seed", type=int, default=3, help="seed of the toy clips (actor, furniture, timing)")
    p.add_argument("--no-gif", action="store_true", help="skip the GIFs (the PNG is always written)")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object on the last line")
    args = p.parse_args(argv)
    out = Path(args.out)
    cases = [_case("sit", "chair", "seat_height", 0.15, args.seed, out),
             _case("lie", "bed", "lie_center", -0.15, args.seed, out)]
    seqs, scenes, titles, frames = [], [], [], []
    for c in cases:  # one panel per (case, version), at the case's middle contact frame
        seqs += c["_seqs"]
        scenes += c["_scenes"]
        titles += ["original", c["case"]]
        frames += [c["frame"]] * 2
        if not args.no_gif:
            render_animation(list(c["_seqs"]), out / f"{c['case'].split()[0]}_side_by_side.gif", list(c["_scenes"]),
                             stride=3, titles=["original", c["case"]])
    png = render_still(seqs, out / "fig2_augment.png", frames, scenes, size_px=360, titles=titles)
    figs = {"cases": [{k: v for k, v in c.items() if not k.startswith("_")} for c in cases], "png": str(png)}
    for c in figs["cases"]:
        print(f"{c['case']:>12}: pelvis {c['pelvis_dz_cm']:+.1f} cm, contact err {c['contact_err_cm']:.2f} cm, "
              f"feet moved {c['foot_move_cm']:.2f} cm, bones {c['bone_length_err_mm']:.1e} mm")
    if args.json:
        print(json.dumps(figs))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
