"""``--shard K/N`` and ``trumans data merge``: build one dataset on many machines with any scheduler.

A dataset build (``data synth``, ``data import``, ``augment``) is a list of independent items: the
rooms and real clips of ``data synth``, the source files (BVH / FBX) or sequences (a TRUMANS release)
of ``data import``, the source sequences of ``augment``. Each item's random stream is seeded by its
position in the full list (``data synth``: ``SeedSequence([seed, room])``; ``augment``:
``default_rng([seed, source])``), never by what else one process happens to run, so

- ``--shard K/N`` (K counts from 1: ``1/N`` .. ``N/N``) runs the items whose position ``i``
  (0-based) has ``i % N == K - 1``: N disjoint shards that together hold every item once;
- a shard's folder holds that shard's files (``sequences/``, ``scenes/``, ``rooms/`` or
  ``records/``) and, written last, ``shard.json`` (``SHARD_FILE``): the command, its settings, the
  inputs' fingerprints, ``K/N``, the number of items, one entry per item done and the files it wrote.
  No ``index.json``: a shard is not a dataset on its own (the train/val/test split is over all items);
- ``trumans data merge OUT SHARD_DIR...`` checks the N manifests (same command, settings and inputs;
  every K from 1 to N once; no item or file in two shards; every listed file present), copies the files
  into ``OUT`` and writes ``index.json`` exactly as the unsharded build would (the command's own
  finishing code, ``FINISHERS``): the merged folder equals the unsharded build (same index, same
  sequence and scene files byte for byte; the per-run timings of ``summary.json`` / ``manifest.json``
  differ). ``OUT`` is written through ``trumans.dataset.DatasetWriter`` (locked, claimed with the
  unsharded command and settings) and ``index.json`` comes last; a merge that fails removes what it
  copied.

An interrupted shard resumes when re-run with the same command line, like an unsharded build.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence, TypeVar

__all__ = ["SHARD_FILE", "MAX_SHARDS", "Shard", "parse_shard", "add_shard_argument", "check_shard_items",
           "shard_files", "write_shard_manifest", "read_shard", "merge_shards", "add_arguments", "run"]

SHARD_FILE = "shard.json"
SHARD_FORMAT = "trumans-shard"
SHARD_VERSION = 1
MAX_SHARDS = 100_000
# the command that wrote a shard -> "module:function" finishing a merged folder from all shards' entries:
# function(writer: DatasetWriter, settings: dict, inputs: dict, entries: list[dict], progress: bool) -> dict
FINISHERS = {
    "data synth": "trumans.synth.build:finish_merged",
    "data import": "trumans.importers.cli:finish_merged",
    "augment": "trumans.augment.pipeline:finish_merged",
}
# files of a shard folder that are not copied into the merged one (besides hidden files: lock, claim, temp)
_NOT_COPIED = (SHARD_FILE, "index.json", "summary.json", "summary.png", "manifest.json")

T = TypeVar("T")


@dataclass(frozen=True)
class Shard:
    """Shard ``k`` of ``n`` (1 <= k <= n): the items at 0-based positions ``i`` with ``i % n == k - 1``."""

    k: int
    n: int

    def __str__(self) -> str:
        return f"{self.k}/{self.n}"

    def owns(self, i: int) -> bool:
        """Whether the item at 0-based position ``i`` of the full list belongs to this shard."""
        return i % self.n == self.k - 1

    def pick(self, items: Sequence[T]) -> list[tuple[int, T]]:
        """``(position, item)`` of this shard's items, in order."""
        return [(i, x) for i, x in enumerate(items) if self.owns(i)]


def parse_shard(text: str) -> Shard:
    """``K/N`` -> Shard (argparse type): whole numbers, 1 <= K <= N <= MAX_SHARDS; anything else is an
    ``argparse.ArgumentTypeError`` naming the accepted form."""
    form = f"give K/N with 1 <= K <= N (K counts from 1; e.g. 1/4 .. 4/4; a Slurm array: --array=1-N and " \
           f"--shard $SLURM_ARRAY_TASK_ID/N)"
    parts = str(text).strip().split("/")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"{text!r} is not a shard; {form}")
    k, n = int(parts[0]), int(parts[1])
    if n < 1 or n > MAX_SHARDS:
        raise argparse.ArgumentTypeError(f"{text!r}: N must be in [1, {MAX_SHARDS:,}]; {form}")
    if k < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: shards count from 1, so K = 0 is none; {form}")
    if k > n:
        raise argparse.ArgumentTypeError(f"{text!r}: K is more than N (there are only {n} shards); {form}")
    return Shard(k, n)


parse_shard.__name__ = "shard"


def add_shard_argument(p: argparse.ArgumentParser, items: str) -> None:
    """``--shard K/N`` on a dataset build; ``items``: what is split (e.g. 'rooms and real clips')."""
    p.add_argument("--shard", type=parse_shard, default=None, metavar="K/N",
                   help=f"build only shard K of N (K = 1..N): the {items} at positions i with i %% N == K-1, into a "
                        f"shard folder that `trumans data merge` joins with the others into the dataset the unsharded "
                        f"command builds (docs/data.md 'Building on many machines')")


def check_shard_items(shard: Shard | None, total: int, items: str) -> None:
    """Refuse a shard with nothing to do (N larger than the ``total`` items), before any work."""
    if shard is not None and shard.k > total:
        raise ValueError(f"--shard {shard}: there are only {total} {items}, so shard {shard.k} of {shard.n} would be "
                         f"empty; use at most {total} shards")


def shard_files(root: str | Path) -> list[str]:
    """Every regular file a shard folder holds for the merge (relative POSIX paths, sorted): all but
    hidden files (lock, claim, output list, temp files) and the top-level ``_NOT_COPIED``."""
    root = Path(root)
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        rel_dir = Path(dirpath).relative_to(root)
        for f in filenames:
            if f.startswith(".") or (rel_dir == Path(".") and f in _NOT_COPIED):
                continue
            p = Path(dirpath) / f
            if p.is_file() and not p.is_symlink():
                out.append((rel_dir / f).as_posix())
    return sorted(out)


def write_shard_manifest(writer, command: str, settings: dict, inputs: dict, shard: Shard, total: int,
                         entries: list[dict]) -> dict:
    """Write ``shard.json`` (module doc) into the writer's folder, last; returns the shard summary.
    ``entries``: one JSON-able dict per item done, each with ``i`` (position in the full list) and
    ``id`` (its unique name: room, source stem); ``settings``: the unsharded command's settings."""
    from trumans.sequence import atomic_write
    from trumans.version import __version__

    root = Path(writer.root)
    manifest = {"format": SHARD_FORMAT, "version": SHARD_VERSION, "trumans": __version__, "command": command,
                "settings": json.loads(json.dumps(settings, sort_keys=True, default=str)), "inputs": inputs,
                "shard": [shard.k, shard.n], "total": int(total),
                "entries": sorted(entries, key=lambda e: e["i"]), "files": shard_files(root)}
    writer.record(SHARD_FILE)
    atomic_write(root / SHARD_FILE, lambda tmp: Path(tmp).write_text(json.dumps(manifest, indent=1)))
    return {"out": str(root), "shard": str(shard), "items": len(entries), "total": int(total),
            "files": len(manifest["files"])}


def read_shard(folder: str | Path) -> dict:
    """The checked ``shard.json`` of a finished shard folder (ValueError / FileNotFoundError naming the fix)."""
    folder = Path(folder)
    path = folder / SHARD_FILE
    if not folder.is_dir():
        raise FileNotFoundError(f"shard folder {folder} does not exist; give the --out folders of the `--shard K/N` runs")
    if not path.is_file():
        hint = (" (it holds a whole dataset, not a shard)" if (folder / "index.json").is_file()
                else " (an unfinished shard: re-run its command, it resumes)")
        raise ValueError(f"{folder} has no {SHARD_FILE}{hint}; give the folders of finished `--shard K/N` runs")
    from trumans.input_files import parse_json

    try:
        m = parse_json(path.read_text(), f"shard manifest {path}", "re-run that shard with --overwrite")
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path} is not valid JSON ({e}); re-run that shard with --overwrite") from e
    ok = (isinstance(m, dict) and m.get("format") == SHARD_FORMAT and isinstance(m.get("command"), str)
          and isinstance(m.get("settings"), dict) and isinstance(m.get("inputs"), dict)
          and isinstance(m.get("shard"), list) and len(m["shard"]) == 2 and all(type(v) is int for v in m["shard"])
          and 1 <= m["shard"][0] <= m["shard"][1] and type(m.get("total")) is int
          and isinstance(m.get("entries"), list) and all(isinstance(e, dict) and type(e.get("i")) is int
                                                         and isinstance(e.get("id"), str) for e in m["entries"])
          and isinstance(m.get("files"), list) and all(isinstance(f, str) for f in m["files"]))
    if not ok:
        raise ValueError(f"{path} is not a trumans shard manifest (format {SHARD_FORMAT} v{SHARD_VERSION}); "
                         f"re-run that shard with --overwrite")
    if m.get("version") != SHARD_VERSION:
        raise ValueError(f"{path} is shard format v{m.get('version')}, this trumans reads v{SHARD_VERSION}; "
                         f"rebuild the shards with this version")
    if m["command"] not in FINISHERS:
        raise ValueError(f"{path}: command {m['command']!r} cannot be merged; shards come from "
                         f"{', '.join(FINISHERS)}")
    from trumans.dataset import _rel_path  # the same rule as the index's paths: relative, inside the folder

    for f in m["files"]:
        _rel_path(path, "'files'", f)
    return m


def _diff(a: dict, b: dict) -> str:
    keys = sorted(set(a) | set(b))
    return "; ".join(f"{k}: {a.get(k)!r} vs {b.get(k)!r}" for k in keys if a.get(k) != b.get(k))[:400]


def check_shards(folders: list[str | Path]) -> list[tuple[Path, dict]]:
    """Read and cross-check the shards of one build (module doc); returns ``(folder, manifest)`` by K.
    Refuses (ValueError naming the shard and the fix): a folder given twice, shards of other commands,
    settings, inputs or N, a K given twice or missing, an item or a file in two shards, an item in the
    wrong shard, a listed file absent."""
    if not folders:
        raise ValueError("no shard folders given; `trumans data merge OUT SHARD_DIR...` needs all N shards")
    seen: dict[Path, str] = {}
    shards: list[tuple[Path, dict]] = []
    for f in folders:
        r = Path(f).resolve()
        if r in seen:
            raise ValueError(f"shard folder {f} is given twice (also as {seen[r]}); give each shard once")
        seen[r] = str(f)
        shards.append((Path(f), read_shard(f)))
    f0, m0 = shards[0]
    for f, m in shards[1:]:
        for key, what in (("command", "command"), ("settings", "settings"), ("inputs", "inputs")):
            if m[key] != m0[key]:
                d = _diff(m0[key], m[key]) if isinstance(m[key], dict) else f"{m0[key]!r} vs {m[key]!r}"
                raise ValueError(f"shards {f0} and {f} come from different builds ({what} differ: {d}); merge the "
                                 f"shards of one command line (only --shard and --out may differ)")
        if m["shard"][1] != m0["shard"][1] or m["total"] != m0["total"]:
            raise ValueError(f"shards {f0} ({m0['shard'][0]}/{m0['shard'][1]}, {m0['total']} items) and {f} "
                             f"({m['shard'][0]}/{m['shard'][1]}, {m['total']} items) split the work differently; "
                             f"give the shards of one N")
    n = m0["shard"][1]
    by_k: dict[int, Path] = {}
    for f, m in shards:
        k = m["shard"][0]
        if k in by_k:
            raise ValueError(f"shard {k}/{n} is given twice ({by_k[k]} and {f}); give each shard once")
        by_k[k] = f
    missing = [k for k in range(1, n + 1) if k not in by_k]
    if missing:
        shown = ", ".join(f"{k}/{n}" for k in missing[:10]) + (" ..." if len(missing) > 10 else "")
        raise ValueError(f"{len(missing)} of {n} shards missing: {shown}; run the command with --shard for each "
                         f"and give all {n} folders")
    item_of: dict[str, Path] = {}
    positions: set[int] = set()
    file_of: dict[str, Path] = {}
    for f, m in shards:
        k = m["shard"][0]
        for e in m["entries"]:
            if e["id"] in item_of:
                raise ValueError(f"item {e['id']!r} is in two shards ({item_of[e['id']]} and {f}); rebuild the "
                                 f"shards of one command line")
            item_of[e["id"]] = f
            if e["i"] % n != k - 1 or not 0 <= e["i"] < m["total"] or e["i"] in positions:
                raise ValueError(f"{f / SHARD_FILE}: item {e['id']!r} (position {e['i']}) does not belong to shard "
                                 f"{k}/{n}; rebuild that shard with --overwrite")
            positions.add(e["i"])
        for rel in m["files"]:
            if rel in file_of:
                raise ValueError(f"{rel} is in two shards ({file_of[rel]} and {f}); the shards overlap; rebuild "
                                 f"them from one command line")
            file_of[rel] = f
            if not (f / rel).is_file():
                raise FileNotFoundError(f"shard {f} lists {rel} but it is missing; re-run that shard (it resumes)")
    if len(positions) != m0["total"]:
        raise ValueError(f"the {n} shards hold {len(positions)} of {m0['total']} items; re-run the shards whose "
                         f"runs stopped early")
    return sorted(shards, key=lambda s: s[1]["shard"][0])


def merge_shards(out: str | Path, folders: list[str | Path], overwrite: bool = False,
                 progress: bool = True) -> dict:
    """Merge the shard folders of one build into the dataset ``out`` (module doc); returns the
    command's summary plus ``merged_shards``. Every check runs before ``out`` is touched."""
    from tqdm import tqdm

    from trumans.dataset import INDEX_FILE, DatasetWriter
    from trumans.sequence import atomic_write

    shards = check_shards(folders)
    out = Path(out)
    ro = out.resolve()
    for f, _ in shards:
        rf = f.resolve()
        if ro == rf or rf in ro.parents or ro in rf.parents:
            raise ValueError(f"OUT {out} is, holds or lies inside the shard folder {f}; merge into a new folder")
    if (out / INDEX_FILE).is_file() and not overwrite:
        raise FileExistsError(f"{out} already holds a dataset; pass --overwrite to replace it, or choose another OUT")
    m0 = shards[0][1]
    module, func = FINISHERS[m0["command"]].split(":")
    finish = getattr(importlib.import_module(module), func)
    entries = sorted((e for _, m in shards for e in m["entries"]), key=lambda e: e["i"])
    files = [(f, rel) for f, m in shards for rel in m["files"]]
    t0 = time.perf_counter()
    with DatasetWriter(out, m0["command"], m0["settings"], overwrite=overwrite) as writer:
        copied: list[str] = []
        try:
            bar = tqdm(total=len(files), desc="merge", unit="file", disable=not progress, file=sys.stderr)
            for f, rel in files:
                writer.record(rel)
                copied.append(rel)
                atomic_write(out / rel, lambda tmp, src=f / rel: shutil.copyfile(src, tmp))
                bar.update(1)
            bar.close()
            summary = finish(writer, m0["settings"], m0["inputs"], entries, progress)
        except BaseException:
            _remove(out, copied + [INDEX_FILE])
            raise
    summary = dict(summary)
    summary.update({"merged_shards": len(shards), "merged_files": len(files),
                    "merge_seconds": time.perf_counter() - t0})
    return summary


def _remove(root: Path, rels: list[str]) -> None:
    """Remove the files ``rels`` under ``root`` and the folders they leave empty (a failed merge)."""
    parents: set[Path] = set()
    for rel in rels:
        p = root / rel
        if p.is_file() and not p.is_symlink():
            p.unlink()
        parents.update(p.parents)
    for d in sorted((d for d in parents if root in d.parents), key=lambda d: len(d.parts), reverse=True):
        try:
            d.rmdir()
        except OSError:
            pass


# ---- `trumans data merge` ----

def add_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.common_args import add_no_progress_argument

    p.add_argument("out", metavar="OUT", help="dataset folder to write (new or empty; as the unsharded command's --out)")
    p.add_argument("shard_dirs", nargs="+", metavar="SHARD_DIR",
                   help="the --out folders of all N runs with --shard 1/N .. N/N, in any order")
    p.add_argument("--overwrite", action="store_true", help="replace the dataset already in OUT")
    add_no_progress_argument(p)
    p.add_argument("--json", action="store_true", help="print a JSON summary as the last line of stdout")


def run(args: argparse.Namespace) -> int:
    from trumans.summary import print_summary

    summary = merge_shards(args.out, args.shard_dirs, overwrite=args.overwrite, progress=not args.no_progress)
    if args.json:
        print_summary(summary)
    else:
        print(f"merged {summary['merged_shards']} shards ({summary['merged_files']} files) into {args.out}: "
              f"{summary.get('sequences', '?')} sequences, hash {summary.get('hash', '?')[:12]}")
    return 0
