"""`trumans data import`: bring a TRUMANS release folder, BVH or FBX files into the dataset format."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from trumans.argtypes import positive_float
from trumans.dataset import DatasetWriter
from trumans.input_files import check_input_file, parse_json
from trumans.sequence import Sequence, save_sequence
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_hidden_alias, out_help
from trumans.shards import add_shard_argument, check_shard_items

INPUT_FORMATS = ["trumans", "bvh", "fbx"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("src", nargs="+", help="a TRUMANS release folder, or one or more .bvh / .fbx files")
    p.add_argument("--input-format", choices=INPUT_FORMATS, default=None,
                   help="layout of SRC (required): trumans (a release folder), bvh or fbx files")
    add_hidden_alias(p, "--format", "input_format", choices=INPUT_FORMATS)  # the spelling before issue 37
    p.add_argument("--out", required=True, help=out_help("folder", "the dataset (sequences/, scenes/, index.json; "
                   "with --shard: the shard's files and shard.json); a folder holding other data is refused unless "
                   "--overwrite"))
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
    add_shard_argument(p, "source files (BVH / FBX) or sequences then scenes (a TRUMANS release)")
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line")


def _read_names(path: str | None) -> list[str] | None:
    if path is None:
        return None
    p = check_input_file(path, "--action-names file", "give a JSON list or a text file with one action name per line")
    text = p.read_text()
    try:
        names = parse_json(text, f"--action-names file {p}", "give a flat JSON list of names or one name per line")
    except json.JSONDecodeError:
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
        jm = parse_json(text, where, "give a flat object like {\"pelvis\": \"Hips\"}")
    except json.JSONDecodeError as e:
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
    entries = write_items(writer, list(enumerate(sequences)), list(enumerate(scene_grids.items(), len(sequences))))
    return _index(writer, entries, name, seed)


def write_items(writer: DatasetWriter, sequences: list[tuple[int, tuple[str, Sequence]]],
                scenes: list[tuple[int, tuple[str, object]]]) -> list[dict]:
    """Write ``(position, (stem, sequence))`` and ``(position, (scene id, occupancy grid))`` items;
    returns one entry per item (what ``_index`` needs; a shard's ``shard.json`` entries)."""
    out = writer.root
    entries = []
    for i, (sid, g) in scenes:
        entries.append({"i": i, "id": f"scene:{sid}", "scene": sid, "dir": writer.save_occupancy(sid, g)})
    for i, (stem, seq) in sequences:
        rel = f"sequences/{stem}.npz"
        writer.record(rel)
        save_sequence(seq, out / rel)
        entries.append({"i": i, "id": stem, "sequence": rel, "group": seq.scene or stem, "frames": int(seq.num_frames),
                        "fps": float(seq.fps), "vocabulary": list(seq.action_names)})
    return sorted(entries, key=lambda e: e["i"])


def _index(writer: DatasetWriter, entries: list[dict], name: str, seed: int) -> dict:
    """The index of all items' ``entries`` (sequences split by scene when there are >= 3, else by
    sequence), written through ``writer.finish``."""
    seqs = [e for e in sorted(entries, key=lambda e: e["i"]) if "sequence" in e]
    scenes_index = {e["scene"]: e["dir"] for e in sorted(entries, key=lambda e: e["i"]) if "scene" in e}
    rels = [e["sequence"] for e in seqs]
    groups = [e["group"] for e in seqs]
    if len(set(groups)) < 3:  # too few scenes to hold any out: split by sequence instead
        groups = [e["id"] for e in seqs]
    splits = {"train": [], "val": [], "test": []}
    for rel, s in zip(rels, split_by_group(groups, seed)):
        splits[s].append(rel)
    index = {
        "name": name, "version": 1, "seed": seed, "fps": seqs[0]["fps"],
        "vocabulary": seqs[0]["vocabulary"], "splits": splits, "scenes": scenes_index,
        "counts": {"sequences": len(rels), "frames": int(sum(e["frames"] for e in seqs))},
    }
    writer.finish(index)
    return index


def finish_merged(writer: DatasetWriter, settings: dict, inputs: dict, entries: list[dict], progress: bool) -> dict:
    """``trumans data merge`` of ``data import`` shards: the index of all shards' items, as the
    unsharded import writes it (``trumans.shards``)."""
    index = _index(writer, entries, inputs["name"], settings["seed"])
    return {"sequences": index["counts"]["sequences"], "frames": index["counts"]["frames"],
            "scenes": len(index["scenes"]), "out": str(writer.root), "hash": index["hash"]}


def run(args: argparse.Namespace) -> int:
    if args.input_format is None:
        raise ValueError("--input-format is required: give trumans (a release folder), bvh or fbx")
    fmt, shard = args.input_format, args.shard
    out = Path(args.out)
    settings = {"format": fmt, "src": [str(Path(p).resolve()) for p in args.src], "seed": args.seed,
                "action_names": args.action_names, "joint_map": args.joint_map, "unit_scale": args.unit_scale,
                "up": args.up, "fps": args.fps, "skeleton": args.skeleton, "feet_on_floor": args.feet_on_floor,
                "labels": args.labels, "keep_first_frame": args.keep_first_frame}
    # read and check everything first: a refused import leaves --out untouched
    if fmt == "trumans":
        from .trumans_release import read_release

        if len(args.src) != 1:
            raise ValueError(f"--input-format trumans takes exactly one release folder, got {len(args.src)}: "
                             f"{' '.join(args.src)[:200]}; import the folders one at a time")
        rel = read_release(args.src[0], action_names=_read_names(args.action_names))
        seqs = rel.sequences
        names = [f"trumans_{i:05d}" for i in range(len(seqs))]
        total = len(seqs) + len(rel.scenes)  # items: the sequences, then the scenes
        check_shard_items(shard, total, "sequences and scenes")
        mine = [i for i in range(len(seqs)) if shard is None or shard.owns(i)]
        if args.fps:
            from trumans.resample import resample_sequence
            seqs = {i: resample_sequence(seqs[i], args.fps) for i in mine}
        named = [(i, (names[i], seqs[i])) for i in mine]
        grids = [(i, sg) for i, sg in enumerate(rel.scenes.items(), len(names)) if shard is None or shard.owns(i)]
        name = f"trumans-import:{Path(args.src[0]).name}"
    else:
        from trumans.importers.bvh import import_bvh
        from trumans.importers.fbx import import_fbx
        from trumans.importers.joint_maps import place_on_floor
        from trumans.importers.labels import drop_converter_tpose, label_sequence

        stems = [Path(src).stem for src in args.src]
        if len(set(stems)) != len(stems):
            raise ValueError(f"{fmt.upper()} files with the same name would overwrite each other: "
                             f"{sorted({s for s in stems if stems.count(s) > 1})}; rename them")
        total = len(args.src)
        check_shard_items(shard, total, "source files")
        joint_map = _read_joint_map(args.joint_map)
        skeleton = None if args.skeleton == "candidates" else args.skeleton
        named = []
        for i, src in enumerate(args.src):
            if shard is not None and not shard.owns(i):
                continue
            # read at the file's rate: a converter's T-pose key is dropped before resampling can blend it in
            fps = args.fps if args.keep_first_frame else None
            if fmt == "bvh":
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
            named.append((i, (stems[i], seq)))
        grids, name = [], f"{fmt}-import"
    if out.resolve() in [Path(p).resolve() for p in args.src] or any(out.resolve() in Path(p).resolve().parents
                                                                     for p in args.src):
        raise ValueError(f"--out {out} is (or holds) the import source; choose another folder")
    if not named and shard is None:
        raise ValueError("the source holds no sequences; there is nothing to import")
    claim = settings if shard is None else {**settings, "shard": str(shard)}
    with DatasetWriter(out, "data import", claim, overwrite=args.overwrite) as writer:
        entries = write_items(writer, named, grids)
        if shard is not None:
            from trumans.shards import write_shard_manifest

            summary = write_shard_manifest(writer, "data import", settings, {"name": name}, shard, total, entries)
            print(f"imported shard {shard} ({summary['items']} of {total} items) into {out}; join all shards with "
                  f"`trumans data merge`", file=sys.stderr)
            if args.json:
                print_summary(summary)
            return 0
        index = _index(writer, entries, name, args.seed)
    summary = {"sequences": index["counts"]["sequences"], "frames": index["counts"]["frames"],
               "scenes": len(index["scenes"]), "out": str(out)}
    print(f"imported {summary['sequences']} sequences ({summary['frames']} frames) into {out}", file=sys.stderr)
    if args.json:
        print_summary(summary)
    return 0
