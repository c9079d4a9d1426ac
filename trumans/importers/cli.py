"""`trumans data import`: bring a TRUMANS release folder, BVH or FBX files into the dataset format."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from trumans.argtypes import positive_float
from trumans.dataset import DatasetWriter
from trumans.input_files import check_input_file
from trumans.sequence import Sequence, save_sequence
from trumans.summary import print_summary
from trumans import argtypes


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("src", nargs="+", help="a TRUMANS release folder, or one or more .bvh / .fbx files")
    p.add_argument("--format", choices=["trumans", "bvh", "fbx"], required=True, help="layout of SRC")
    p.add_argument("--out", required=True, help="dataset folder to write (sequences/, scenes/, index.json); "
                                                "a folder holding other data is refused unless --overwrite")
    p.add_argument("--overwrite", action="store_true", help="replace the dataset already in --out")
    p.add_argument("--action-names", help="TRUMANS: JSON list or text file (one per line) naming the label columns")
    p.add_argument("--joint-map", help="BVH/FBX: JSON object {our_joint_name: their_joint_name} overriding the "
                                       "map, inline or in a .json file")
    p.add_argument("--skeleton", default="auto", choices=["auto", "daz", "cmu_mb", "candidates"],
                   help="BVH/FBX: built-in joint map (default auto: detected; candidates: the name lists)")
    p.add_argument("--unit-scale", type=positive_float, help="BVH/FBX: metres per file unit (default: BVH guessed "
                   "from the skeleton size, FBX from its UnitScaleFactor)")
    p.add_argument("--up", choices=["y", "z"], default="y", help="BVH: up axis of the file (default y; FBX files say)")
    p.add_argument("--feet-on-floor", action="store_true",
                   help="BVH/FBX: move each motion vertically so its feet stand on z = 0 (without it, feet "
                        "more than 10 cm off the floor are reported)")
    p.add_argument("--fps", type=positive_float, help="resample to this frame rate (default: keep the file's)")
    p.add_argument("--labels", choices=["motion", "none"], default="motion",
                   help="BVH/FBX: action labels; motion (default): every frame labelled with its body state "
                        "(stand, walk, turn, sit_down, sit, stand_up, lie_down, lie, get_up) read from the motion, "
                        "so `trumans train` can use the data; none: no labels")
    p.add_argument("--keep-first-frame", action="store_true",
                   help="BVH/FBX: keep a first frame that is a converter's synthetic T-pose (dropped by default)")
    p.add_argument("--seed", type=argtypes.seed, default=0, help="seed of the train/val/test split")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def _read_names(path: str | None) -> list[str] | None:
    if path is None:
        return None
    p = check_input_file(path, "--action-names file", "give a JSON list or a text file with one action name per line")
    text = p.read_text()
    try:
        names = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        names = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise ValueError(f"--action-names {path} must hold a JSON list of strings or one name per line")
    return names


def _read_joint_map(arg: str | None) -> dict[str, str] | None:
    """--joint-map: inline JSON (starts with '{') or a JSON file holding an object of strings."""
    if arg is None:
        return None
    if arg.lstrip().startswith("{"):
        text, where = arg, "inline --joint-map"
    else:
        p = Path(arg)
        if not p.is_file():
            raise FileNotFoundError(f"--joint-map {arg!r} is neither inline JSON nor an existing file; give "
                                    f"'{{\"pelvis\": \"Hips\"}}' or a .json file")
        text, where = p.read_text(), f"--joint-map file {p}"
    try:
        jm = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as e:  # RecursionError: nested too deep
        raise ValueError(f"{where} is not valid JSON ({e}); give an object like {{\"pelvis\": \"Hips\"}}") from e
    if not isinstance(jm, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in jm.items()):
        raise ValueError(f"{where} must be a JSON object of joint names {{our_joint: bvh_joint}}, got "
                         f"{str(jm)[:60]}")
    return jm


def split_by_group(groups: list[str], seed: int, fracs: tuple[float, float] = (0.8, 0.1)) -> list[str]:
    """Assign each item the split of its group (e.g. scene): returns 'train' | 'val' | 'test' per item.
    Three or more groups: at least one val and one test group; two: one train, one val (training needs a
    validation split); one: train."""
    uniq = sorted(set(groups))
    rng = np.random.default_rng(seed)
    order = [uniq[i] for i in rng.permutation(len(uniq))]
    n = len(order)
    n_val = max(1, round(fracs[1] * n)) if n >= 3 else (1 if n == 2 else 0)
    n_test = max(1, round((1 - fracs[0] - fracs[1]) * n)) if n >= 3 else 0
    which = {g: ("val" if i < n_val else "test" if i < n_val + n_test else "train") for i, g in enumerate(order)}
    return [which[g] for g in groups]


def write_dataset(writer: DatasetWriter, sequences: list[tuple[str, Sequence]], scene_grids: dict,
                  name: str, seed: int) -> dict:
    """Write sequences + occupancy-only scenes + the hashed index.json through ``writer``; returns the index."""
    if not sequences:
        raise ValueError("the source holds no sequences; there is nothing to import")
    out = writer.root
    scenes_index = {sid: writer.save_occupancy(sid, g) for sid, g in scene_grids.items()}
    rels = []
    for stem, seq in sequences:
        rel = f"sequences/{stem}.npz"
        save_sequence(seq, out / rel)
        rels.append(rel)
    groups = [seq.scene or stem for stem, seq in sequences]
    if len(set(groups)) < 3:  # too few scenes to hold any out: split by sequence instead
        groups = [stem for stem, _ in sequences]
    splits = {"train": [], "val": [], "test": []}
    for rel, s in zip(rels, split_by_group(groups, seed)):
        splits[s].append(rel)
    index = {
        "name": name, "version": 1, "seed": seed, "fps": float(sequences[0][1].fps),
        "vocabulary": list(sequences[0][1].action_names), "splits": splits, "scenes": scenes_index,
        "counts": {"sequences": len(rels), "frames": int(sum(s.num_frames for _, s in sequences))},
    }
    writer.finish(index)
    return index


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    settings = {"format": args.format, "src": [str(Path(p).resolve()) for p in args.src], "seed": args.seed,
                "action_names": args.action_names, "joint_map": args.joint_map, "unit_scale": args.unit_scale,
                "up": args.up, "fps": args.fps, "skeleton": args.skeleton, "feet_on_floor": args.feet_on_floor,
                "labels": args.labels, "keep_first_frame": args.keep_first_frame}
    # read and check everything first: a refused import leaves --out untouched
    if args.format == "trumans":
        from .trumans_release import read_release

        if len(args.src) != 1:
            raise ValueError(f"--format trumans takes exactly one release folder, got {len(args.src)}: "
                             f"{' '.join(args.src)[:200]}; import the folders one at a time")
        rel = read_release(args.src[0], action_names=_read_names(args.action_names))
        seqs = rel.sequences
        if args.fps:
            from trumans.resample import resample_sequence
            seqs = [resample_sequence(s, args.fps) for s in seqs]
        named = [(f"trumans_{i:05d}", s) for i, s in enumerate(seqs)]
        grids, name = rel.scenes, f"trumans-import:{Path(args.src[0]).name}"
    else:
        from trumans.importers.bvh import import_bvh
        from trumans.importers.fbx import import_fbx
        from trumans.importers.joint_maps import place_on_floor
        from trumans.importers.labels import drop_converter_tpose, label_sequence

        joint_map = _read_joint_map(args.joint_map)
        skeleton = None if args.skeleton == "candidates" else args.skeleton
        named = []
        for src in args.src:
            # read at the file's rate: a converter's T-pose key is dropped before resampling can blend it in
            fps = args.fps if args.keep_first_frame else None
            if args.format == "bvh":
                seq = import_bvh(src, joint_map=joint_map, unit_scale=args.unit_scale, up=args.up, fps=fps,
                                 skeleton=skeleton, feet_on_floor=args.feet_on_floor)
            else:
                seq = import_fbx(src, joint_map=joint_map, unit_scale=args.unit_scale, fps=fps,
                                 skeleton=skeleton, feet_on_floor=args.feet_on_floor)
            if not args.keep_first_frame:
                seq, dropped = drop_converter_tpose(seq)
                if dropped and args.feet_on_floor:  # the floor height without the T-pose frame
                    seq = place_on_floor(seq, True, source=src)
                if args.fps:
                    from trumans.resample import resample_sequence

                    seq = resample_sequence(seq, args.fps)
            if args.labels == "motion":
                seq = label_sequence(seq)
            named.append((Path(src).stem, seq))
        stems = [s for s, _ in named]
        if len(set(stems)) != len(stems):
            raise ValueError(f"{args.format.upper()} files with the same name would overwrite each other: "
                             f"{sorted({s for s in stems if stems.count(s) > 1})}; rename them")
        grids, name = {}, f"{args.format}-import"
    if out.resolve() in [Path(p).resolve() for p in args.src] or any(out.resolve() in Path(p).resolve().parents
                                                                     for p in args.src):
        raise ValueError(f"--out {out} is (or holds) the import source; choose another folder")
    with DatasetWriter(out, "data import", settings, overwrite=args.overwrite) as writer:
        index = write_dataset(writer, named, grids, name=name, seed=args.seed)
    summary = {"sequences": index["counts"]["sequences"], "frames": index["counts"]["frames"],
               "scenes": len(index["scenes"]), "out": str(out)}
    print(f"imported {summary['sequences']} sequences ({summary['frames']} frames) into {out}", file=sys.stderr)
    if args.json:
        print_summary(summary)
    return 0
