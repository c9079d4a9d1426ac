"""Augment a dataset: every interactable object a sequence touches -> N variations (TRUMANS §3.3).

Output folder (a dataset in the DESIGN.md format, so training can read it alone or next to the
original): ``sequences/<stem>__<object>_v<k>.npz``, ``scenes/<scene id>/`` (the changed scene),
``records/<stem>.json`` (one per source sequence, written last: its presence with a matching key
marks the sequence done, so an interrupted run resumes), ``manifest.json`` (what changed: source,
variation, contact offsets, figures per output) and ``index.json`` (splits mirror the sources').
Sequences are processed in parallel by worker processes. The same seed gives the same outputs.
"""
from __future__ import annotations

import hashlib
import json
import multiprocessing as mp
import os
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from scenes.io import save_scene
from scenes.scene import Scene
from trumans.contacts.rule import FLOOR_NAME, HOLD_THRESHOLD
from trumans.dataset import Dataset, content_hash, write_index
from trumans.metrics import joint_centre_inside_cm
from trumans.sequence import Sequence, atomic_write, save_sequence

from .core import AugmentConfig, augment_many, sequence_contacts
from .variations import KINDS, sample_variation

__all__ = ["PipelineConfig", "augment_dataset", "contacted_objects", "vary_sequence"]


@dataclass(frozen=True)
class PipelineConfig:
    """data: source dataset folder; out: output folder; variations: per touched object (the paper
    uses 2); splits: source splits to augment; kinds: variation kinds to draw from; workers:
    processes (0 = CPU count); occupancy: also cache each new scene's occupancy grid;
    max_penetration: a variation whose new motion puts a joint centre deeper than this (m) inside
    the changed object (``trumans.metrics.joint_centre_inside_cm``) is redrawn (up to ``tries`` times) and otherwise skipped; so is one whose IK
    leaves more than ``max_unreachable`` of its contact frames unreachable (1.0 = keep all)."""

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

    def __post_init__(self) -> None:
        if self.variations < 1:
            raise ValueError(f"variations must be >= 1, got {self.variations}")
        bad = [k for k in self.kinds if k not in KINDS]
        if bad or not self.kinds:
            raise ValueError(f"kinds must be a non-empty subset of {KINDS}, got {self.kinds}")
        if self.workers < 0:
            raise ValueError(f"workers must be >= 0 (0 = all CPUs), got {self.workers}")
        if not 0.0 <= self.max_unreachable <= 1.0:
            raise ValueError(f"max_unreachable must be a fraction in [0, 1], got {self.max_unreachable}")

    def key(self, src: Path) -> str:
        """Resume key of one source sequence: settings + the source file's bytes."""
        h = hashlib.sha256(json.dumps({k: v for k, v in asdict(self).items() if k not in ("workers", "out")},
                                      sort_keys=True).encode())
        h.update(src.read_bytes())
        return h.hexdigest()[:16]


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
        raise ValueError(f"sequence (scene {scene.name!r}) has no contact with any interactable object; "
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


def _process(args: tuple[PipelineConfig, int, str, str]) -> dict:
    cfg, idx, rel, split = args
    torch_threads()
    ds = Dataset(cfg.data)
    src = ds.root / rel
    out = Path(cfg.out)
    stem = Path(rel).stem
    record = out / "records" / f"{stem}.json"
    key = cfg.key(src)
    if record.is_file():
        try:
            rec = json.loads(record.read_text())
            if rec.get("key") == key:
                return rec
        except (json.JSONDecodeError, UnicodeDecodeError):
            pass
    seq = ds.load(rel)
    scene = ds.scene(seq.scene)
    rng = np.random.default_rng([cfg.seed, idx])
    items = []
    try:
        results = vary_sequence(seq, scene, cfg.variations, rng, _library(ds, _CACHE), cfg)
    except ValueError as e:
        results, err = [], str(e)
    else:
        err = ""
    for name, k, res in results:
        if res is None:
            items.append({"object": name, "k": k, "skipped": "every draw put a joint centre inside the changed object or left too many contacts unreachable"})
            continue
        sid = f"{scene.name}__{stem}__{name}_v{k}"
        res.scene.name = sid
        res.sequence.scene = sid
        save_scene(res.scene, out / "scenes" / sid)
        if cfg.occupancy:
            from scenes.occupancy import scene_occupancy
            scene_occupancy(res.scene, out / "scenes" / sid)
        seq_rel = f"sequences/{stem}__{name}_v{k}.npz"
        save_sequence(res.sequence, out / seq_rel)
        items.append({"object": name, "k": k, "sequence": seq_rel, "scene": sid, "scene_dir": f"scenes/{sid}",
                      "source_scene": scene.name, **res.report})
    rec = {"key": key, "source": rel, "split": split, "frames": seq.num_frames, "outputs": items, "error": err}
    atomic_write(record, lambda tmp: Path(tmp).write_text(json.dumps(rec, indent=1)))
    return rec


_CACHE: dict = {}


def torch_threads() -> None:
    """One thread per worker process (the machine is shared)."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        import torch
        torch.set_num_threads(1)
    except ImportError:  # torch is optional here
        pass


def augment_dataset(cfg: PipelineConfig, progress: bool = True) -> dict:
    """Run the pipeline (module doc); returns the summary written into manifest.json."""
    t0 = time.perf_counter()
    ds = Dataset(cfg.data)
    jobs = []
    for split in cfg.splits:
        for i, p in enumerate(ds.split(split)):
            jobs.append((cfg, len(jobs), str(p.relative_to(ds.root)), split))
    if not jobs:
        raise ValueError(f"no sequences in splits {cfg.splits} of {cfg.data}")
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    workers = cfg.workers or os.cpu_count() or 1
    recs: list[dict] = []
    bar = _bar(len(jobs), progress)
    if workers == 1:
        for j in jobs:
            recs.append(_process(j))
            bar.update(1)
    else:
        with mp.get_context("spawn").Pool(workers, initializer=torch_threads) as pool:
            for r in pool.imap(_process, jobs):
                recs.append(r)
                bar.update(1)
    bar.close()
    outputs = [dict(o, source=r["source"], split=r["split"]) for r in recs for o in r["outputs"] if "sequence" in o]
    splits: dict[str, list[str]] = {s: [] for s in cfg.splits}
    for o in outputs:
        splits[o["split"]].append(o["sequence"])
    scenes = {o["scene"]: o["scene_dir"] for o in outputs}
    files = [o["sequence"] for o in outputs]
    index = {"name": f"{ds.name}-augmented", "version": "1", "seed": cfg.seed, "fps": ds.fps,
             "vocabulary": ds.vocabulary, "splits": splits, "scenes": scenes,
             "counts": {s: len(v) for s, v in splits.items()}, "hash": content_hash(out, files),
             "source": {"name": ds.name, "hash": ds.hash}}
    write_index(out, index)
    # contact error weighted by each output's contact frames (a per-output mean would let a
    # handful of 3-frame contacts count as much as a 2000-frame sitting)
    cframes = np.array([o["contact_frames"] for o in outputs], np.float64)
    cerr = np.array([o["contact_err_cm"] for o in outputs], np.float64)
    unreachable = int(sum(o["unreachable_frames"] for o in outputs))
    frames_out = int(sum(int(o.get("frames", 0)) for o in outputs))
    seconds = time.perf_counter() - t0
    summary = {
        "sources": len(recs), "outputs": len(outputs),
        "skipped": sum(1 for r in recs for o in r["outputs"] if "skipped" in o),
        "errors": [{"source": r["source"], "error": r["error"]} for r in recs if r["error"]],
        "frames_out": frames_out,
        "contact_frames": int(cframes.sum()),
        "contact_err_cm": float((cerr * cframes).sum() / cframes.sum()) if cframes.sum() else 0.0,
        "unreachable_frames": unreachable,
        "unreachable_frac": unreachable / cframes.sum() if cframes.sum() else 0.0,
        "seconds": seconds,
        "frames_per_s": frames_out / max(seconds, 1e-9),  # wall clock, this run (resumed sources count too)
        "workers": workers,
        "config": asdict(cfg),
    }
    manifest = {"summary": summary, "outputs": outputs}
    atomic_write(out / "manifest.json", lambda tmp: Path(tmp).write_text(json.dumps(manifest, indent=1)))
    return summary


def _bar(n: int, on: bool):
    try:
        from tqdm import tqdm
        return tqdm(total=n, disable=not on, desc="augment", file=sys.stderr)
    except ImportError:  # tqdm is installed in the env; keep working without it
        class _Nop:
            def update(self, k: int) -> None: ...
            def close(self) -> None: ...
        return _Nop()
