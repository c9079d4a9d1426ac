"""Build the embedded synthetic HSI dataset: procedural rooms x scripted takes, in parallel over rooms.

Layout written under ``out`` (docs/conventions.md "File formats"):
``scenes/<room>/`` (scene.json + meshes + occupancy.npz), ``sequences/<room>_<take>.npz``,
``rooms/<room>.json`` (per-room record, written last: its presence with a matching key marks the
room complete, so an interrupted build resumes), ``index.json`` and ``summary.json``.
Every file is written atomically. Rooms are split train/val/test by room (never a room in two
splits). The same seed gives the same arrays.
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

from trumans.dataset import SPLITS, DatasetWriter, record_outputs
from trumans.sequence import atomic_write, save_sequence
from trumans.eval import metrics
from trumans.limits import MAX_ROOMS, MAX_SYNTH_HOURS, check_count
from trumans.workers import worker_pool
from .vocab import SYNTH_ACTIONS

__all__ = ["SynthConfig", "build_dataset", "finish_merged", "room_ids", "split_rooms", "DATASET_NAME", "DATASET_VERSION"]

DATASET_NAME = "trumans-synth"
DATASET_VERSION = "1"
FPS = 30


@dataclass(frozen=True)
class SynthConfig:
    """out: dataset folder; hours: total motion (h); rooms: number of procedural rooms; seed;
    workers: processes (rooms in parallel); take_seconds: (min, max) take length (s);
    split: train/val/test fractions of the rooms; real_share: share of the mocap corpus's train
    clips added as real takes, each in a room of its own (``real_takes``; 0 = procedural only)."""

    out: str
    hours: float = 2.0
    rooms: int = 50
    seed: int = 0
    workers: int = 0  # 0 = os.cpu_count()
    take_seconds: tuple[float, float] = (30.0, 90.0)
    split: tuple[float, float, float] = (0.8, 0.1, 0.1)
    real_share: float = 0.0

    def __post_init__(self) -> None:
        if not (self.hours > 0 and math.isfinite(self.hours)):
            raise ValueError(f"hours must be > 0, got {self.hours}")
        if self.rooms < 1:
            raise ValueError(f"rooms must be >= 1, got {self.rooms}")
        check_count(self.rooms, MAX_ROOMS, "MAX_ROOMS", "rooms")
        check_count(self.hours, MAX_SYNTH_HOURS, "MAX_SYNTH_HOURS", "hours")
        if self.workers < 0:
            raise ValueError(f"workers must be >= 0 (0 = all CPUs), got {self.workers}")
        lo, hi = self.take_seconds
        if not 0 < lo <= hi:
            raise ValueError(f"take_seconds must be (min, max) with 0 < min <= max, got {self.take_seconds}")
        if len(self.split) != 3 or min(self.split) < 0 or abs(sum(self.split) - 1) > 1e-6:
            raise ValueError(f"split must be three fractions summing to 1, got {self.split}")
        if not 0.0 <= self.real_share <= 1.0:
            raise ValueError(f"real_share must be in [0, 1] (the share of the corpus's train clips), got {self.real_share}")

    @property
    def room_frames(self) -> int:
        """Frames of motion per room."""
        return int(math.ceil(self.hours * 3600 * FPS / self.rooms))


def room_ids(n: int) -> list[str]:
    return [f"room_{i:03d}" for i in range(n)]


def split_rooms(ids: list[str], seed: int, fractions: tuple[float, float, float] = (0.8, 0.1, 0.1)) -> dict[str, list[str]]:
    """Shuffle room ids with ``seed`` and cut them train/val/test; val and test get at least one
    room each when there are >= 3 rooms (with 2 rooms: one train, one val)."""
    order = [ids[i] for i in np.random.default_rng([seed, 7]).permutation(len(ids))]
    n = len(order)
    n_val = int(round(fractions[1] * n))
    n_test = int(round(fractions[2] * n))
    if n >= 3:
        n_val, n_test = max(n_val, 1 if fractions[1] > 0 else 0), max(n_test, 1 if fractions[2] > 0 else 0)
    elif n == 2:
        n_val, n_test = 1, 0
    else:
        n_val = n_test = 0
    n_train = n - n_val - n_test
    return {"train": sorted(order[:n_train]), "val": sorted(order[n_train:n_train + n_val]),
            "test": sorted(order[n_train + n_val:])}


def _room_key(cfg: SynthConfig, index: int) -> str:
    s = json.dumps([DATASET_VERSION, cfg.seed, index, cfg.room_frames, list(cfg.take_seconds), FPS])
    return hashlib.sha256(s.encode()).hexdigest()[:16]


def _settings(cfg: SynthConfig) -> dict:
    """The settings that define the data (``real_share`` only when real takes are asked for, so a
    procedural-only build is byte-identical to one made before real takes existed)."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()
            if k not in ("out", "workers") and not (k == "real_share" and v == 0)}


def _real_job(job: tuple) -> dict:
    """Build the room and take of one real clip (``real_takes.build_real_room``)."""
    from .real_takes import REAL_VERSION, build_real_room

    cfg, clip = job
    name_seed = int(hashlib.sha256(clip.name.encode()).hexdigest()[:8], 16)
    key = hashlib.sha256(json.dumps([DATASET_VERSION, REAL_VERSION, cfg.seed, clip.name, len(clip.joints)]).encode())
    return build_real_room(Path(cfg.out), clip, _room_seed(cfg.seed, name_seed), key.hexdigest()[:16])


def _run_job(job: tuple) -> dict:
    return _real_job(job[1:]) if job[0] == "real" else _build_room(job[1:])


def _room_seed(seed: int, index: int) -> int:
    return int(np.random.SeedSequence([seed, index]).generate_state(1)[0])


def _build_room(args: tuple[SynthConfig, int]) -> dict:
    """Generate one room and its takes; returns the room record (also written to rooms/<id>.json)."""
    cfg, index = args
    from trumans.scenes.io import save_scene, scene_files
    from trumans.scenes.occupancy import scene_occupancy
    from trumans.scenes.procedural import make_room

    from .script import script_room

    out = Path(cfg.out)
    rid = room_ids(cfg.rooms)[index]
    key = _room_key(cfg, index)
    rec_path = out / "rooms" / f"{rid}.json"
    if rec_path.is_file():
        try:
            rec = json.loads(rec_path.read_text())
            if rec.get("key") == key and all((out / p).is_file() for p in rec["sequences"]) \
                    and (out / rec["scene_dir"] / "occupancy.npz").is_file():
                rec["resumed"] = True
                return rec
        except (json.JSONDecodeError, KeyError, TypeError, RecursionError):
            pass  # unreadable record: rebuild the room
    t0 = time.perf_counter()
    scene = make_room(_room_seed(cfg.seed, index))
    scene.name = rid
    scene_dir = out / "scenes" / rid
    record_outputs(out, [f"scenes/{rid}/{f}" for f in scene_files(scene)])
    save_scene(scene, scene_dir)
    occ = scene_occupancy(scene, scene_dir)
    rng = np.random.default_rng([cfg.seed, index, 1])
    takes = script_room(scene, occ, rng, total_frames=cfg.room_frames, take_seconds=cfg.take_seconds, fps=FPS)
    record_outputs(out, [f"sequences/{rid}_t{k:02d}.npz" for k in range(len(takes))] + [f"rooms/{rid}.json"])
    seqs, frames, slides, gaps = [], 0, [], []
    bone_dev = pen = 0.0
    action_frames = {a: 0 for a in SYNTH_ACTIONS}
    categories: dict[str, int] = {}
    activities: dict[str, dict[str, int]] = {}
    for k, take in enumerate(takes):
        for act, n in take.done.items():
            activities.setdefault(act, {"done": 0, "skipped": 0})["done"] += n
        for act, why in take.skipped.items():
            activities.setdefault(act, {"done": 0, "skipped": 0})["skipped"] += len(why)
        rel = f"sequences/{rid}_t{k:02d}.npz"
        take.sequence.scene = rid
        save_sequence(take.sequence, out / rel)
        seq = take.sequence
        seqs.append(rel)
        frames += seq.num_frames
        bone_dev = max(bone_dev, metrics.bone_length_dev_mm(seq.joints, take.offsets))
        pen = max(pen, metrics.penetration_max_cm(take.penetration))
        slides.append(metrics.foot_slides(seq.joints[:, [10, 11]], take.foot_floor))
        gaps.append(np.asarray(take.grasp_gaps, dtype=np.float64))
        on = seq.actions > 0
        for a, name in enumerate(seq.action_names):
            action_frames[name] = action_frames.get(name, 0) + int(on[:, a].sum())
        for ob in seq.objects.values():
            categories[ob.category] = categories.get(ob.category, 0) + 1
    for ob in scene.objects.values():
        categories.setdefault(ob.category, 0)
    slides_a = np.concatenate(slides) if slides else np.zeros(0)
    gaps_a = np.concatenate(gaps) if gaps else np.zeros(0)
    rec = {
        "room": rid, "key": key, "scene_dir": f"scenes/{rid}", "sequences": seqs, "frames": frames,
        "action_frames": action_frames, "categories": categories, "activities": activities,
        "skip_examples": {a: why[:2] for t in takes for a, why in t.skipped.items()},
        "scene_categories": sorted({o.category for o in scene.objects.values()}),
        "bone_length_dev_mm": bone_dev, "penetration_max_cm": pen,
        "foot_slide_sum_m": float(slides_a.sum()), "foot_steps": int(len(slides_a)),
        "grasp_gap_sum_m": float(gaps_a.sum()), "grasp_frames": int(len(gaps_a)),
        "seconds": time.perf_counter() - t0,
    }

    def _write(tmp: str) -> None:
        with open(tmp, "w") as f:
            json.dump(rec, f, indent=1)

    atomic_write(rec_path, _write)
    return rec


def _init_worker() -> None:
    os.environ["OMP_NUM_THREADS"] = "1"
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # torch is a dependency, but the builder itself does not need it
        pass


def build_dataset(cfg: SynthConfig, progress: bool = True, overwrite: bool = False, shard=None) -> dict:
    """Build (or resume) the dataset of ``cfg``; returns the summary figures (also in summary.json).
    The folder is locked while building and must be new, empty or a build of the same settings
    (``trumans.dataset.DatasetWriter``; ``overwrite`` replaces what it holds). Workers die with
    the builder (kill -9 leaves no orphan writing); rerunning resumes from the finished rooms.
    ``shard`` (``trumans.shards.Shard``): build only its rooms and real clips (each seeded by its
    position, so its files are those of the unsharded build) and write ``shard.json`` instead of
    the index; ``trumans data merge`` joins the shards (``finish_merged``).

    Summary: sequences, frames, hours, rooms, action_frames (per action), frames_per_s (frames
    generated in this run per wall-clock second), bone_length_dev_mm, foot_skate_per_step_cm (mean slide
    per planned floor step), penetration_max_cm, grasp_dist_cm (see ``trumans.eval.metrics``), splits, categories,
    activities (per scripted activity: performed / skipped as infeasible), hash."""
    from trumans.shards import check_shard_items

    jobs: list[tuple] = [("room", cfg, i) for i in range(cfg.rooms)]
    if cfg.real_share > 0:
        from .real_takes import train_clips

        jobs += [("real", cfg, clip) for clip in train_clips(cfg.real_share, cfg.seed)]
    check_shard_items(shard, len(jobs), "rooms and real clips")
    settings = _settings(cfg) if shard is None else {**_settings(cfg), "shard": str(shard)}
    with DatasetWriter(cfg.out, "data synth", settings, overwrite=overwrite) as writer:
        return _build(cfg, writer, progress, jobs, shard)


def _build(cfg: SynthConfig, writer: DatasetWriter, progress: bool, jobs: list[tuple], shard=None) -> dict:
    from tqdm import tqdm

    t0 = time.perf_counter()
    workers = cfg.workers or os.cpu_count() or 1
    total = len(jobs)
    if shard is not None:
        mine = shard.pick(jobs)
        jobs, positions = [j for _, j in mine], [i for i, _ in mine]
    records: list[dict] = []
    bar = tqdm(total=len(jobs), desc="synth rooms", unit="room", disable=not progress, file=sys.stderr)
    if workers == 1 or len(jobs) == 1:
        _init_worker()
        for job in jobs:
            records.append(_run_job(job))
            bar.update(1)
    else:
        with worker_pool(min(workers, len(jobs)), "fork") as pool:
            for rec in pool.imap(_run_job, jobs):
                records.append(rec)
                bar.update(1)
    bar.close()
    if shard is not None:
        from trumans.shards import write_shard_manifest

        entries = [{"i": i, "id": r["room"], "record": {k: v for k, v in r.items() if k != "resumed"}}
                   for i, r in zip(positions, records)]
        return write_shard_manifest(writer, "data synth", _settings(cfg), {"version": DATASET_VERSION}, shard,
                                    total, entries)
    return _finish(cfg, writer, records, time.perf_counter() - t0, workers)


def finish_merged(writer: DatasetWriter, settings: dict, inputs: dict, entries: list[dict], progress: bool) -> dict:
    """``trumans data merge`` of ``data synth`` shards: the index, summary.json and summary.png of all
    shards' room records, as the unsharded build writes them (``trumans.shards``)."""
    if inputs.get("version") != DATASET_VERSION:
        raise ValueError(f"the shards are of dataset version {inputs.get('version')}, this trumans builds "
                         f"{DATASET_VERSION}; rebuild them with this version")
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in settings.items()}
    cfg = SynthConfig(out=str(writer.root), workers=1, **kw)
    return _finish(cfg, writer, [e["record"] for e in entries], 0.0, 1)  # nothing generated: frames_per_s 0


def _finish(cfg: SynthConfig, writer: DatasetWriter, records: list[dict], elapsed: float, workers: int) -> dict:
    """Index, summary.json and summary.png of the room records (all rooms and real clips of ``cfg``)."""
    out = writer.root
    real_records = sorted((r for r in records if "real" in r), key=lambda r: r["room"])
    records = sorted((r for r in records if "real" not in r), key=lambda r: r["room"])
    placed = [r for r in real_records if not r.get("skipped")]

    ids = [r["room"] for r in records]
    splits_rooms = split_rooms(ids, cfg.seed, cfg.split)
    if placed:  # real rooms are split on their own (the procedural split stays as it was)
        real_split = split_rooms([r["room"] for r in placed], cfg.seed, cfg.split)
        splits_rooms = {s: sorted(splits_rooms[s] + real_split[s]) for s in SPLITS}
    records = sorted(records + placed, key=lambda r: r["room"])
    by_room = {r["room"]: r for r in records}
    splits = {s: [p for rid in splits_rooms[s] for p in by_room[rid]["sequences"]] for s in SPLITS}
    frames = sum(r["frames"] for r in records)
    new_frames = sum(r["frames"] for r in records if not r.get("resumed"))
    action_frames = {a: sum(r["action_frames"].get(a, 0) for r in records) for a in SYNTH_ACTIONS}
    categories: dict[str, int] = {}
    for r in records:
        for c in r["scene_categories"]:
            categories[c] = categories.get(c, 0) + 1
    moved: dict[str, int] = {}
    for r in records:
        for c, n in r["categories"].items():
            moved[c] = moved.get(c, 0) + n
    activities: dict[str, dict[str, int]] = {}
    for r in records:
        for act, c in r.get("activities", {}).items():
            agg = activities.setdefault(act, {"done": 0, "skipped": 0})
            agg["done"] += c["done"]
            agg["skipped"] += c["skipped"]
    steps = sum(r["foot_steps"] for r in records)
    grasp_frames = sum(r["grasp_frames"] for r in records)
    files = [p for s in SPLITS for p in splits[s]]
    summary = {
        "out": str(out),
        "sequences": len(files),
        "frames": frames,
        "hours": frames / FPS / 3600.0,
        "rooms": len(records),
        "action_frames": action_frames,
        "actions_missing": [a for a, n in action_frames.items() if n == 0],
        "frames_per_s": new_frames / elapsed if elapsed > 0 else 0.0,
        "seconds": elapsed,
        "workers": workers,
        "bone_length_dev_mm": max((r["bone_length_dev_mm"] for r in records), default=0.0),
        "foot_skate_per_step_cm": 100.0 * sum(r["foot_slide_sum_m"] for r in records) / max(steps, 1),
        "foot_steps": steps,
        "penetration_max_cm": max((r["penetration_max_cm"] for r in records), default=0.0),
        "grasp_dist_cm": 100.0 * sum(r["grasp_gap_sum_m"] for r in records) / max(grasp_frames, 1),
        "grasp_frames": grasp_frames,
        "scene_categories": categories,
        "object_tracks": moved,
        "activities": activities,
        "splits": {s: {"rooms": len(splits_rooms[s]), "sequences": len(splits[s]),
                       "frames": sum(by_room[rid]["frames"] for rid in splits_rooms[s])} for s in SPLITS},
        "resumed_rooms": sum(1 for r in records if r.get("resumed")),
    }
    if cfg.real_share > 0:
        summary["real"] = {
            "clips": len(real_records), "takes": len(placed), "skipped": len(real_records) - len(placed),
            "skipped_clips": [r["real"] for r in real_records if r.get("skipped")],
            "frames": sum(r["frames"] for r in placed), "hours": sum(r["frames"] for r in placed) / FPS / 3600.0,
            "rooms_with_furniture_removed": sum(1 for r in placed if r.get("removed_for_path")),
            "fitted_objects": sum(len(r.get("fitted", [])) for r in placed),
            "fit_error_max_mm": max((r["fit_error_max_mm"] for r in placed), default=0.0),
        }
    index = {
        "name": DATASET_NAME, "version": DATASET_VERSION, "seed": cfg.seed, "fps": FPS,
        "vocabulary": list(SYNTH_ACTIONS), "splits": splits,
        "split_rooms": splits_rooms,
        "scenes": {r["room"]: r["scene_dir"] for r in records},
        "counts": {"sequences": len(files), "frames": frames, "rooms": len(records),
                   "action_frames": action_frames, "scene_categories": categories},
        "config": _settings(cfg),
    }
    if cfg.real_share > 0:
        index["real"] = {p: r["real"] for r in placed for p in r["sequences"]}
    summary["hash"] = writer.finish(index)
    writer.record("summary.json", "summary.png")

    def _write(tmp: str) -> None:
        with open(tmp, "w") as f:
            json.dump(summary, f, indent=1)

    atomic_write(out / "summary.json", _write)
    _summary_figure(out / "summary.png", summary)
    return summary


def _summary_figure(path: Path, summary: dict) -> None:
    """Bar charts of the seconds per action and the rooms per object category (PNG, atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.5), gridspec_kw={"width_ratios": [3, 2]})
    names = list(summary["action_frames"])
    a.bar(names, [summary["action_frames"][n] / FPS for n in names], color="tab:blue")
    a.set_ylabel("seconds")
    a.set_title(f"{summary['hours']:.2f} h, {summary['sequences']} takes, {summary['rooms']} rooms")
    a.tick_params(axis="x", rotation=70)
    cats = sorted(summary["scene_categories"])
    b.bar(cats, [summary["scene_categories"][c] for c in cats], color="tab:green")
    b.set_ylabel("rooms containing it")
    b.tick_params(axis="x", rotation=70)
    fig.tight_layout()

    def _write(tmp: str) -> None:
        fig.savefig(tmp, format="png", dpi=80)

    atomic_write(path, _write)
    plt.close(fig)
