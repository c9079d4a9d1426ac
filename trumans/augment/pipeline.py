"""Augment a dataset: every interactable object a sequence touches -> N variations (TRUMANS §3.3).

Output folder (a dataset in the docs/conventions.md format, so training can read it alone or next to the
original): ``sequences/<stem>__<object>_v<k>.npz``, ``scenes/<scene id>/`` (the changed scene),
``records/<stem>.json`` (one per source sequence, written last: its presence with a matching key
marks the sequence done, so an interrupted run resumes), ``manifest.json`` (what changed: source,
variation, contact offsets, figures per output) and ``index.json`` (splits mirror the sources').
Sequences are processed in parallel by worker processes (as many as there are sequences to do, at
most ``workers``; they die with the parent). The same seed gives the same outputs.

Resume: a record is reused only if its key matches: the settings, the sequence's position, its
bytes, and the bytes of every scene folder of the source dataset (a changed mesh or pose anywhere
can change the outputs: replacements come from all scenes). A source whose processing fails is not
recorded (the next run retries it) and makes the run fail after the others are done. A source that
touches no interactable object is recorded as having nothing to augment. The output folder is locked
(one writer) and must be new, empty or this run's own (``DatasetWriter``).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from trumans.scenes.io import save_scene, scene_files
from trumans.scenes.scene import Scene
from trumans.contacts.rule import FLOOR_NAME, HOLD_THRESHOLD
from trumans.dataset import Dataset, DatasetWriter, content_hash, record_outputs
from trumans.eval.metrics import joint_centre_inside_cm
from trumans.limits import MAX_VARIATIONS
from trumans.sequence import Sequence, atomic_write, save_sequence

from trumans.augment.core import AugmentConfig, augment_many, sequence_contacts
from trumans.augment.variations import KINDS, sample_variation

SOURCES = ("all", "real", "procedural")

__all__ = ["PipelineConfig", "augment_dataset", "finish_merged", "contacted_objects", "vary_sequence"]


@dataclass(frozen=True)
class PipelineConfig:
    """data: source dataset folder; out: output folder; variations: per touched object (the paper
    uses 2); splits: source splits to augment; kinds: variation kinds to draw from; workers:
    processes (0 = CPU count); occupancy: also cache each new scene's occupancy grid;
    max_penetration: a variation whose new motion puts a joint centre deeper than this (m) inside
    the changed object (``trumans.eval.metrics.joint_centre_inside_cm``) is redrawn (up to ``tries`` times) and otherwise skipped; so is one whose IK
    leaves more than ``max_unreachable`` of its contact frames unreachable (1.0 = keep all); source:
    which takes of a ``trumans data synth`` dataset (its index lists the mocap ones under 'real'):
    all, real or procedural."""

    data: str
    out: str
    variations: int = 2
    seed: int = 0
    splits: tuple[str, ...] = ("train",)
    kinds: tuple[str, ...] = KINDS
    workers: int = 0
    occupancy: bool = False
    window_s: float = 1.0
    threshold: float = HOLD_THRESHOLD
    max_penetration: float = 0.03
    max_unreachable: float = 0.1
    tries: int = 4
    source: str = "all"

    def __post_init__(self) -> None:
        if len(set(self.splits)) != len(self.splits):
            raise ValueError(f"splits {list(self.splits)} name a split twice; give each split once")
        if not 1 <= self.variations <= MAX_VARIATIONS:
            raise ValueError(f"variations must be in [1, {MAX_VARIATIONS}] per touched object, got {self.variations}")
        for name in ("window_s", "threshold", "max_penetration"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v}")
        if self.tries < 1:
            raise ValueError(f"tries must be >= 1, got {self.tries}")
        bad = [k for k in self.kinds if k not in KINDS]
        if bad or not self.kinds:
            raise ValueError(f"kinds must be a non-empty subset of {KINDS}, got {self.kinds}")
        if self.workers < 0:
            raise ValueError(f"workers must be >= 0 (0 = all CPUs), got {self.workers}")
        if not 0.0 <= self.max_unreachable <= 1.0:
            raise ValueError(f"max_unreachable must be a fraction in [0, 1], got {self.max_unreachable}")
        if self.source not in SOURCES:
            raise ValueError(f"source must be one of {SOURCES}, got {self.source!r}")

    def settings(self) -> dict:
        """What the outputs depend on (not ``out`` or ``workers``); ``data`` as an absolute path."""
        d = {k: v for k, v in asdict(self).items() if k not in ("workers", "out") and not (k == "source" and v == "all")}
        d["data"] = str(Path(self.data).resolve())
        return d

    def key(self, src: Path, index: int, scenes_digest: str) -> str:
        """Resume key of one source sequence: settings, its position ``index`` (its random
        stream), its bytes and ``scenes_digest`` (``scenes_digest(ds)``)."""
        h = hashlib.sha256(json.dumps(self.settings(), sort_keys=True, default=list).encode())
        h.update(f"|{index}|{scenes_digest}|".encode())
        h.update(src.read_bytes())
        return h.hexdigest()[:16]


class NothingToAugment(ValueError):
    """The sequence touches no interactable object."""


def scenes_digest(ds: Dataset) -> str:
    """SHA-256 of every scene folder's files (scene.json, meshes; not the occupancy cache)."""
    files = sorted(str(p.relative_to(ds.root)) for sid in ds.scene_ids for p in ds.scene_dir(sid).rglob("*")
                   if p.is_file() and p.name != "occupancy.npz" and not p.name.endswith(".tmp"))
    return content_hash(ds.root, files)


def _check_once(jobs: list[tuple], ds: Dataset) -> None:
    """Rule: each source sequence is augmented once. An index that lists a sequence twice (in one
    split or in two of the augmented splits), or two sequences of one file name (outputs and
    records are named by it), is refused naming both entries, before any work."""
    seen: dict[str, tuple[str, str]] = {}
    for _, _, rel, split in jobs:
        stem = Path(rel).stem
        if stem in seen:
            first, first_split = seen[stem]
            what = "is listed twice" if first == rel else f"has the file name of {first}"
            raise ValueError(f"{ds.root / 'index.json'}: {rel} (split {split}) {what} (split {first_split}); "
                             f"augment writes one set of outputs per sequence name: list each sequence once")
        seen[stem] = (rel, split)


def contacted_objects(intervals, scene: Scene) -> list[str]:
    """Interactable objects of ``scene`` that some contact interval touches (sorted)."""
    return sorted({iv.obj for iv in intervals if iv.obj != FLOOR_NAME and iv.obj in scene.objects})


def _library(ds: Dataset, cache: dict) -> dict[str, dict[str, trimesh.Trimesh]]:
    """category -> {"<scene>/<object>": mesh} over every scene of the dataset (cached per process)."""
    if "lib" not in cache:
        lib: dict[str, dict[str, trimesh.Trimesh]] = {}
        for sid in ds.scene_ids:
            for n, o in ds.scene(sid).objects.items():
                lib.setdefault(o.category, {})[f"{sid}/{n}"] = o.mesh
        cache["lib"] = lib
    return cache["lib"]


def vary_sequence(seq: Sequence, scene: Scene, n: int, rng: np.random.Generator,
                  library: dict[str, dict[str, trimesh.Trimesh]], cfg: PipelineConfig,
                  acfg: AugmentConfig | None = None) -> list[tuple[str, int, object]]:
    """All augmentations of one sequence: [(object, k, AugmentOutput or None if every draw failed)].

    Contacts are found once; all variations are solved in one IK batch, and draws that put a joint
    centre deeper than max(original, ``cfg.max_penetration``) inside the changed object, or leave
    more than ``cfg.max_unreachable`` of their contact frames unreachable, are redrawn."""
    acfg = acfg or AugmentConfig(window_s=cfg.window_s, threshold=cfg.threshold)
    sc = sequence_contacts(seq, scene, acfg)
    objs = contacted_objects(sc.intervals, scene)
    if not objs:
        raise NothingToAugment(f"sequence (scene {scene.name!r}) has no contact with any interactable object; "
                               "nothing to augment")
    libs = {name: {k: m for k, m in library.get(scene.objects[name].category, {}).items()
                   if k != f"{scene.name}/{name}"} for name in objs}
    pen0 = {name: joint_centre_inside_cm(sc.joints, scene, [name]) for name in objs}
    slots = [(name, k) for name in objs for k in range(n)]
    done: dict[tuple[str, int], object] = {}
    todo = slots
    for round_ in range(cfg.tries):
        if not todo:
            break
        draws = [sample_variation(scene.objects[name], rng, cfg.kinds, libs[name]) for name, _ in todo]
        lib = {k: m for name, _ in todo for k, m in libs[name].items()}
        outs = augment_many([(sc, [v]) for v in draws], lib, acfg)
        again = []
        for slot, out in zip(todo, outs):
            pen = joint_centre_inside_cm(out.sequence.joints, out.scene, [slot[0]])
            out.report["joint_centre_inside_cm"] = pen
            unreach = out.report["unreachable_frames"] / max(out.report["contact_frames"], 1)
            if pen <= max(pen0[slot[0]], cfg.max_penetration * 100) and unreach <= cfg.max_unreachable:
                done[slot] = out
            else:
                again.append(slot)
        todo = again
    return [(name, k, done.get((name, k))) for name, k in slots]


def _process(args: tuple[PipelineConfig, int, str, str, str]) -> dict:
    """Augment one source; returns its record (written to records/ unless it failed)."""
    cfg, idx, rel, split, key = args
    torch_threads()
    stem = Path(rel).stem
    try:
        return _augment_source(cfg, idx, rel, split, key, stem)
    except NothingToAugment as e:
        rec = {"key": key, "source": rel, "split": split, "frames": 0, "outputs": [], "error": "",
               "nothing_to_augment": str(e)}
    except (ValueError, OSError) as e:  # bad input in this source: reported, retried next run
        (Path(cfg.out) / "records" / f"{stem}.json").unlink(missing_ok=True)  # an older record is stale now
        return {"key": key, "source": rel, "split": split, "frames": 0, "outputs": [],
                "error": " ".join(str(e).split()) or type(e).__name__}
    record = Path(cfg.out) / "records" / f"{stem}.json"
    record_outputs(cfg.out, [f"records/{stem}.json"])
    atomic_write(record, lambda tmp: Path(tmp).write_text(json.dumps(rec, indent=1)))
    return rec


def _augment_source(cfg: PipelineConfig, idx: int, rel: str, split: str, key: str, stem: str) -> dict:
    ds = Dataset(cfg.data)
    out = Path(cfg.out)
    seq = ds.load(rel)
    scene = ds.scene(seq.scene)
    rng = np.random.default_rng([cfg.seed, idx])
    items = []
    results = vary_sequence(seq, scene, cfg.variations, rng, _library(ds, _CACHE), cfg)
    for name, k, res in results:
        if res is None:
            items.append({"object": name, "k": k, "skipped": "every draw put a joint centre inside the changed object or left too many contacts unreachable"})
            continue
        sid = f"{scene.name}__{stem}__{name}_v{k}"
        res.scene.name = sid
        res.sequence.scene = sid
        seq_rel = f"sequences/{stem}__{name}_v{k}.npz"
        record_outputs(out, [f"scenes/{sid}/{f}" for f in scene_files(res.scene, occupancy=cfg.occupancy)] + [seq_rel])
        save_scene(res.scene, out / "scenes" / sid)
        if cfg.occupancy:
            from trumans.scenes.occupancy import scene_occupancy
            scene_occupancy(res.scene, out / "scenes" / sid)
        save_sequence(res.sequence, out / seq_rel)
        items.append({"object": name, "k": k, "sequence": seq_rel, "scene": sid, "scene_dir": f"scenes/{sid}",
                      "source_scene": scene.name, **res.report})
    rec = {"key": key, "source": rel, "split": split, "frames": seq.num_frames, "outputs": items, "error": ""}
    record_outputs(out, [f"records/{stem}.json"])
    atomic_write(out / "records" / f"{stem}.json", lambda tmp: Path(tmp).write_text(json.dumps(rec, indent=1)))
    return rec


def _done_record(out: Path, rel: str, key: str) -> dict | None:
    """The record of a source finished by an earlier run with the same key (its outputs present)."""
    path = out / "records" / f"{Path(rel).stem}.json"
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(rec, dict) or rec.get("key") != key or rec.get("error") or not isinstance(rec.get("outputs"), list):
        return None
    if not all(isinstance(o, dict) and ("sequence" not in o or (out / str(o["sequence"])).is_file()
                                        and (out / str(o.get("scene_dir", ""))).is_dir()) for o in rec["outputs"]):
        return None
    return rec


_CACHE: dict = {}


def torch_threads() -> None:
    """One thread per worker process (the machine is shared)."""
    from trumans.workers import one_thread

    one_thread()


def augment_dataset(cfg: PipelineConfig, progress: bool = True, overwrite: bool = False, shard=None) -> dict:
    """Run the pipeline (module doc); returns the summary written into manifest.json. ``overwrite``
    replaces another dataset or run in ``cfg.out``. Raises ValueError after writing the index and
    manifest of what succeeded if some sources failed (they are retried by the next run).
    ``shard`` (``trumans.shards.Shard``): augment only its source sequences (each seeded by its
    position among all sources, so its outputs are those of the unsharded run) and write
    ``shard.json`` instead of the index and manifest; ``trumans data merge`` joins the shards."""
    t0 = time.perf_counter()
    ds = Dataset(cfg.data)
    out = Path(cfg.out)
    if out.resolve() == ds.root.resolve() or out.resolve() in ds.root.resolve().parents:
        raise ValueError(f"--out {out} is (or holds) the source dataset --data {cfg.data}; writing there would "
                         f"replace its index; choose another --out")
    real = set(ds.index.get("real", {}))  # a `trumans data synth` dataset lists its mocap takes here
    jobs = []
    for split in cfg.splits:
        for p in ds.split(split):
            rel = str(p.relative_to(ds.root))
            if cfg.source == "all" or (rel in real) == (cfg.source == "real"):
                jobs.append((cfg, len(jobs), rel, split))
    if not jobs:
        raise ValueError(f"no {'' if cfg.source == 'all' else cfg.source + ' '}sequences in splits {list(cfg.splits)} "
                         f"of {cfg.data}; choose splits (or --source) that hold some")
    _check_once(jobs, ds)
    total = len(jobs)
    if shard is not None:
        from trumans.shards import check_shard_items

        check_shard_items(shard, total, "source sequences")
        jobs = [j for j in jobs if shard.owns(j[1])]
    digest = scenes_digest(ds)
    jobs = [(c, i, rel, split, cfg.key(ds.root / rel, i, digest)) for c, i, rel, split in jobs]
    settings = cfg.settings() if shard is None else {**cfg.settings(), "shard": str(shard)}
    with DatasetWriter(out, "augment", settings, overwrite=overwrite) as writer:
        recs: list[dict | None] = [_done_record(out, rel, key) for _, _, rel, _, key in jobs]
        todo = [j for j, r in zip(jobs, recs) if r is None]
        workers = max(1, min(cfg.workers or os.cpu_count() or 1, len(todo)))
        bar = _bar(len(jobs), progress)
        bar.update(len(jobs) - len(todo))
        fresh: list[dict] = []
        if workers == 1:
            for j in todo:
                fresh.append(_process(j))
                bar.update(1)
        else:
            from trumans.workers import worker_pool

            with worker_pool(workers, "spawn") as pool:
                for r in pool.imap(_process, todo):
                    fresh.append(r)
                    bar.update(1)
        bar.close()
        it = iter(fresh)
        recs = [r if r is not None else next(it) for r in recs]
        if shard is not None:
            return _finish_shard(cfg, ds, digest, writer, jobs, recs, total, shard)
        return _finish(cfg, ds, writer, recs, workers, time.perf_counter() - t0)


@dataclass(frozen=True)
class _SourceInfo:
    """What the index takes from the source dataset (``Dataset``'s fields of that name)."""

    name: str
    fps: float
    vocabulary: list
    hash: str


def _finish_shard(cfg: PipelineConfig, ds: Dataset, digest: str, writer: DatasetWriter, jobs: list[tuple],
                  recs: list[dict], total: int, shard) -> dict:
    """``shard.json`` of a sharded run (``trumans.shards``); refused while a source of the shard failed."""
    from trumans.shards import write_shard_manifest

    failed = [r for r in recs if r["error"]]
    if failed:
        raise ValueError(f"{len(failed)} of {len(recs)} source sequences of shard {shard} failed (e.g. "
                         f"{failed[0]['source']}: {failed[0]['error'][:200]}); fix them and re-run the same command "
                         f"(finished sources resume); the shard is not mergeable until every source is done")
    source = {"name": ds.name, "fps": ds.fps, "vocabulary": ds.vocabulary, "hash": ds.hash}
    entries = [{"i": j[1], "id": j[2], "record": r} for j, r in zip(jobs, recs)]
    return write_shard_manifest(writer, "augment", cfg.settings(), {"source": source, "scenes_digest": digest},
                                shard, total, entries)


def finish_merged(writer: DatasetWriter, settings: dict, inputs: dict, entries: list[dict], progress: bool) -> dict:
    """``trumans data merge`` of ``augment`` shards: index.json and manifest.json of all shards' source
    records, as the unsharded run writes them (``trumans.shards``)."""
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in settings.items()}
    cfg = PipelineConfig(out=str(writer.root), workers=1, **kw)
    return _finish(cfg, _SourceInfo(**inputs["source"]), writer, [e["record"] for e in entries], 1, 0.0)


def _finish(cfg: PipelineConfig, ds: Dataset, writer: DatasetWriter, recs: list[dict], workers: int,
            seconds: float) -> dict:
    """Index, manifest and summary of the records; raises if some sources failed."""
    out = writer.root
    outputs = [dict(o, source=r["source"], split=r["split"]) for r in recs for o in r["outputs"] if "sequence" in o]
    splits: dict[str, list[str]] = {s: [] for s in cfg.splits}
    for o in outputs:
        splits[o["split"]].append(o["sequence"])
    scenes = {o["scene"]: o["scene_dir"] for o in outputs}
    files = [o["sequence"] for o in outputs]
    index = {"name": f"{ds.name}-augmented", "version": "1", "seed": cfg.seed, "fps": ds.fps,
             "vocabulary": ds.vocabulary, "splits": splits, "scenes": scenes,
             "counts": {s: len(v) for s, v in splits.items()}, "source": {"name": ds.name, "hash": ds.hash}}
    # contact error weighted by each output's contact frames (a per-output mean would let a
    # handful of 3-frame contacts count as much as a 2000-frame sitting)
    cframes = np.array([o["contact_frames"] for o in outputs], np.float64)
    cerr = np.array([o["contact_err_cm"] for o in outputs], np.float64)
    unreachable = int(sum(o["unreachable_frames"] for o in outputs))
    frames_out = int(sum(int(o.get("frames", 0)) for o in outputs))
    failed = [{"source": r["source"], "error": r["error"]} for r in recs if r["error"]]
    summary = {
        "sources": len(recs), "outputs": len(outputs),
        "nothing_to_augment": sum(1 for r in recs if r.get("nothing_to_augment")),
        "skipped": sum(1 for r in recs for o in r["outputs"] if "skipped" in o),
        # which variations were not written and why (the command warns naming each object: never a silent drop)
        "skipped_outputs": [{"source": r["source"], "object": o["object"], "k": o["k"], "why": o["skipped"]}
                            for r in recs for o in r["outputs"] if "skipped" in o],
        "errors": failed,
        "frames_out": frames_out,
        "contact_frames": int(cframes.sum()),
        "contact_err_cm": float((cerr * cframes).sum() / cframes.sum()) if cframes.sum() else 0.0,
        "unreachable_frames": unreachable,
        "unreachable_frac": unreachable / cframes.sum() if cframes.sum() else 0.0,
        "seconds": seconds,
        "frames_per_s": frames_out / seconds if seconds > 0 else 0.0,  # wall clock, this run (resumed sources count too; 0 for a merge)
        "workers": workers,
        "config": asdict(cfg),
    }
    if files:
        summary["hash"] = writer.finish(index)
    else:
        (out / "index.json").unlink(missing_ok=True)  # an index of an earlier run would list nothing of this one
    manifest = {"summary": summary, "outputs": outputs}
    writer.record("manifest.json")
    atomic_write(out / "manifest.json", lambda tmp: Path(tmp).write_text(json.dumps(manifest, indent=1)))
    if failed:
        raise SourcesFailed(summary, f"{len(failed)} of {len(recs)} source sequences failed (e.g. {failed[0]['source']}: "
                                     f"{failed[0]['error'][:200]}); fix them and re-run the same command: finished "
                                     f"sources resume, failed ones are retried (all failures in {out / 'manifest.json'})")
    if not files:
        raise ValueError(f"no output: none of the {len(recs)} source sequences touches an interactable object "
                         f"that could be varied; nothing was augmented into {out}")
    return summary


class SourcesFailed(ValueError):
    """Some sources failed; ``summary`` holds the figures of the ones that did not."""

    def __init__(self, summary: dict, message: str) -> None:
        super().__init__(message)
        self.summary = summary


def _bar(n: int, on: bool):
    try:
        from tqdm import tqdm
        return tqdm(total=n, disable=not on, desc="augment", file=sys.stderr)
    except ImportError:  # tqdm is installed in the env; keep working without it
        class _Nop:
            def update(self, k: int) -> None: ...
            def close(self) -> None: ...
        return _Nop()
