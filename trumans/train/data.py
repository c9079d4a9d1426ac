"""Training data: episodes cut from a dataset folder, canonicalised, with action labels and local grids.

Every sequence of a split is resampled to ``DataSection.fps`` (10 Hz), cut into windows of
``episode_frames`` frames every ``stride`` frames, and each window is put in its canonical frame
(``trumans.model.episodes``). Its conditions come from ``trumans.model.conditions.episode_condition``
(the one definition the sampler uses too): the scene condition is the local occupancy grid
around the episode subgoal - the pelvis floor point at the last frame - turned to the heading of
the first frame, with the scene's dynamic objects where they are at the episode's first frame
(``trumans.scenes.scene_grids``; TRUMANS §4.3). Grids are computed once per split and cached bit-packed in
``cache_dir`` (keyed by the dataset's index, the data config and the vocabulary), so batches are
array slices and the loader is never the bottleneck.

The batch stream is a pure function of (seed, step, rank): sample position ``p`` of the
infinite stream is element ``p mod N`` of the epoch ``p div N`` permutation, so a resumed run
sees exactly the batches an uninterrupted run would, and DDP ranks take disjoint slices.
"""
from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from trumans.actions import remap_labels
from trumans.dataset import Dataset
from trumans.model.conditions import episode_condition, episode_scene_grids
from trumans.model.episodes import FeatureLayout, Normalizer, canonicalize, episode_starts
from trumans.resample import resample_sequence
from trumans.sequence import atomic_write

from trumans.train.config import DataSection
from trumans.scenes.occupancy import DEFAULT_VOXEL, OCCUPANCY_FILE
from trumans.scenes.scene_grids import SceneGrids

__all__ = ["EpisodeSet", "build_episodes", "load_episodes", "BatchStream", "Batch", "RecentOnly"]

_CACHE_VERSION = "episodes-v2"


@dataclass
class EpisodeSet:
    """features: (N, L, F) float32 canonical (unnormalised); actions: (N, L, N_A) float32;
    grids: (N, n^3 / 8) uint8 bit-packed local grids (axes forward, left, up; True = occupied);
    origin: (N, 3) world m; yaw: (N,) rad; sequence: (N,) int index into ``files``; start: (N,) frame."""

    features: np.ndarray
    actions: np.ndarray
    grids: np.ndarray
    origin: np.ndarray
    yaw: np.ndarray
    sequence: np.ndarray
    start: np.ndarray
    grid_n: int
    files: list[str]

    def __len__(self) -> int:
        return int(self.features.shape[0])

    @classmethod
    def concat(cls, sets: list["EpisodeSet"]) -> "EpisodeSet":
        """One set holding the episodes of ``sets`` in order (``sequence`` re-indexed into the joint ``files``)."""
        if len({s.grid_n for s in sets}) != 1 or len({s.features.shape[1:] for s in sets}) != 1 \
                or len({s.actions.shape[1:] for s in sets}) != 1:
            raise ValueError("episode sets differ in grid size, feature layout or vocabulary; they cannot be joined")
        offsets = np.cumsum([0] + [len(s.files) for s in sets[:-1]])
        cat = lambda name: np.concatenate([getattr(s, name) for s in sets])  # noqa: E731
        return cls(cat("features"), cat("actions"), cat("grids"), cat("origin"), cat("yaw"),
                   np.concatenate([s.sequence + o for s, o in zip(sets, offsets)]), cat("start"), sets[0].grid_n,
                   [f for s in sets for f in s.files])

    def unpack_grids(self, idx: np.ndarray) -> np.ndarray:
        """(B,) indices -> (B, n, n, n) bool grids."""
        n = self.grid_n
        return np.unpackbits(self.grids[idx], axis=1, count=n ** 3).astype(bool).reshape(len(idx), n, n, n)


def _cut(seq, cfg: DataSection, layout: FeatureLayout, vocab: list[str]):
    L = cfg.episode_frames
    starts = episode_starts(seq.num_frames, L, cfg.stride)
    if len(starts) == 0:
        return None
    win = starts[:, None] + np.arange(L)[None]  # (N, L)
    joints = seq.joints[win]  # (N, L, 24, 3)
    if seq.actions is not None and len(seq.action_names):
        labels = remap_labels(np.asarray(seq.actions, np.float32), seq.action_names, vocab)
    else:
        labels = np.zeros((seq.num_frames, len(vocab)), np.float32)
    cond = episode_condition(joints, labels[win], progress_indicator=cfg.progress_indicator)
    origin, yaw = cond.origin, cond.yaw
    if layout.rotations:
        if seq.rotations is None:
            raise ValueError("the feature layout has rotations but a sequence has none; set data.rotations = false")
        cj, cr = canonicalize(joints, origin, yaw, rotations=seq.rotations[win])
        feats = layout.pack(cj, cr)
    else:
        feats = layout.pack(canonicalize(joints, origin, yaw))
    return feats, cond, starts


def _scene_grids(ds: Dataset, scene_id: str, dynamic: bool, memo: dict) -> SceneGrids:
    """The scene's episode grids. Without a cached occupancy.npz (augmented scenes are written
    without one) the grids are built from scene.json; ``memo`` shares the voxelised static part and
    object meshes between scene variations."""
    has_json = (ds.scene_dir(scene_id) / "scene.json").is_file()
    has_occ = (ds.scene_dir(scene_id) / OCCUPANCY_FILE).is_file()
    if has_json and (dynamic or not has_occ):
        return SceneGrids(ds.occupancy(scene_id) if has_occ else None, ds.scene(scene_id), voxel=DEFAULT_VOXEL,
                          memo=memo)
    return SceneGrids(ds.occupancy(scene_id))


def _cache_key(ds: Dataset, split: str, cfg: DataSection, layout: FeatureLayout, vocab: list[str], files: list[str]) -> str:
    h = hashlib.sha256(_CACHE_VERSION.encode())
    episode_fields = {k: v for k, v in asdict(cfg).items() if k != "augmented_share"}  # batch mixing, not episodes
    h.update(json.dumps([ds.hash or ds.name, split, episode_fields, asdict(layout), vocab, files], sort_keys=True).encode())
    if not ds.hash:  # no content hash: key on the sequence files' sizes and times
        for f in files:
            st = (ds.root / f).stat()
            h.update(f"{f}:{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()[:16]


_SCENES_HELD = 8  # scenes whose grids build_episodes keeps between sequences


class RecentOnly(OrderedDict):
    """A dict that keeps its ``size`` most recently used entries (reads count as use)."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.size = size

    def __getitem__(self, key):
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key, value) -> None:
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.size:
            self.popitem(last=False)


def build_episodes(ds: Dataset, split: str, cfg: DataSection, vocab: list[str],
                   progress: bool = False) -> EpisodeSet:
    """Cut every sequence of ``split`` into episodes (see module doc). Raises ValueError if none fit."""
    from tqdm import tqdm

    layout = FeatureLayout(rotations=cfg.rotations)
    augmented = set(ds.index.get("augmented", []))
    files = [p for p in ds.index["splits"].get(split, []) if cfg.augmented or p not in augmented]
    parts: list = []
    # a few scenes' grids at a time: a scene's full-resolution occupancy is megabytes, and a dataset
    # with thousands of scenes (every real take and augmented variation has its own) held them all
    occ_cache: OrderedDict = OrderedDict()
    memo = RecentOnly(_SCENES_HELD * 4)  # voxelised static parts / object meshes shared between scene variations
    n = cfg.grid
    for si, rel in enumerate(tqdm(files, desc=f"episodes[{split}]", disable=not progress, leave=False)):
        seq = resample_sequence(ds.load(rel), cfg.fps)
        cut = _cut(seq, cfg, layout, vocab)
        if cut is None:
            continue
        feats, cond, starts = cut
        if seq.scene:
            if seq.scene not in occ_cache:
                occ_cache[seq.scene] = _scene_grids(ds, seq.scene, cfg.dynamic_objects, memo)
                while len(occ_cache) > _SCENES_HELD:
                    occ_cache.popitem(last=False)
            occ_cache.move_to_end(seq.scene)
            poses = {k: o.pose[starts] for k, o in seq.objects.items()} if cfg.dynamic_objects else None
            grids = episode_scene_grids(occ_cache[seq.scene], cond, poses, n=n, extent=cfg.extent)
        else:  # no scene recorded: open floor (nothing occupied above z = 0)
            grids = np.zeros((len(feats), n, n, n), dtype=bool)
        packed = np.packbits(grids.reshape(len(grids), -1), axis=1)
        parts.append((feats, cond.actions, packed, cond.origin, cond.yaw, np.full(len(feats), si), starts))
    if not parts:
        raise ValueError(f"split {split!r} of {ds.root} has no sequence with >= {cfg.episode_frames} frames at "
                         f"{cfg.fps} fps; use a larger dataset or shorter episodes")
    cols = [np.concatenate([p[i] for p in parts]) for i in range(7)]
    return EpisodeSet(cols[0].astype(np.float32), cols[1].astype(np.float32), cols[2], cols[3], cols[4],
                      cols[5].astype(np.int64), cols[6].astype(np.int64), n, files)


def load_episodes(ds: Dataset, split: str, cfg: DataSection, vocab: list[str], cache_dir: str | Path | None,
                  progress: bool = False, write_cache: bool = True) -> EpisodeSet:
    """``build_episodes`` with an on-disk cache ``cache_dir/episodes-<split>-<key>.npz``."""
    layout = FeatureLayout(rotations=cfg.rotations)
    files = list(ds.index["splits"].get(split, []))
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"episodes-{split}-{_cache_key(ds, split, cfg, layout, vocab, files)}.npz"
        if path.is_file():
            try:
                with np.load(path, allow_pickle=False) as z:
                    return EpisodeSet(z["features"], z["actions"], z["grids"], z["origin"], z["yaw"],
                                      z["sequence"], z["start"], int(z["grid_n"]), [str(f) for f in z["files"]])
            except (OSError, ValueError, KeyError):
                pass  # corrupt cache: rebuild below
    eps = build_episodes(ds, split, cfg, vocab, progress)
    if path is not None and write_cache:
        arrays = dict(features=eps.features, actions=eps.actions, grids=eps.grids, origin=eps.origin, yaw=eps.yaw,
                      sequence=eps.sequence, start=eps.start, grid_n=np.asarray(eps.grid_n),
                      files=np.asarray(eps.files, dtype=np.str_))

        def write(tmp: str) -> None:
            with open(tmp, "wb") as f:
                np.savez(f, **arrays)

        atomic_write(path, write)
    return eps


@dataclass
class Batch:
    """x: (B, L, F) normalised features; actions: (B, L, N_A); scene: (B, n, n, n) bool; index: (B,)."""

    x: torch.Tensor
    actions: torch.Tensor
    scene: torch.Tensor
    index: np.ndarray


class BatchStream:
    """Deterministic batches: ``batch(step, rank, world)`` is a pure function of the seed and its args.

    groups: (N,) pool of each episode (0 .. P-1) and shares: (P,) the fraction of every global batch
    drawn from each pool (e.g. original vs augmented episodes); each pool is walked through its own
    per-epoch permutations, so over many steps pool p gives exactly ``shares[p]`` of the samples.
    Without groups all episodes are drawn alike."""

    def __init__(self, episodes: EpisodeSet, normalizer: Normalizer, global_batch: int, seed: int,
                 groups: np.ndarray | None = None, shares: Sequence[float] | None = None) -> None:
        if global_batch < 1:
            raise ValueError(f"batch size must be >= 1, got {global_batch}")
        self.eps, self.norm, self.global_batch, self.seed = episodes, normalizer, global_batch, seed
        self.x = torch.from_numpy(normalizer.normalize(episodes.features).astype(np.float32))
        self.actions = torch.from_numpy(episodes.actions)
        self._perms: dict[tuple[int, int], np.ndarray] = {}
        if (groups is None) != (shares is None):
            raise ValueError("give both groups and shares, or neither")
        if groups is None:
            self.pools, self.cum_shares = [np.arange(len(episodes))], np.array([0.0, 1.0])
        else:
            groups, shares = np.asarray(groups), np.asarray(shares, np.float64)
            if groups.shape != (len(episodes),) or shares.ndim != 1 or len(shares) == 0:
                raise ValueError(f"groups must be ({len(episodes)},) and shares (P,), got {groups.shape} and {shares.shape}")
            if not np.all(np.isfinite(shares)) or np.any(shares < 0) or abs(shares.sum() - 1) > 1e-6:
                raise ValueError(f"shares must be fractions >= 0 that sum to 1, got {shares.tolist()}")
            self.pools = [np.flatnonzero(groups == p) for p in range(len(shares))]
            empty = [p for p, idx in enumerate(self.pools) if len(idx) == 0 and shares[p] > 0]
            if empty:
                raise ValueError(f"pool(s) {empty} have a share of the batch but no episodes")
            self.cum_shares = np.concatenate([[0.0], np.cumsum(shares)])
            self.cum_shares[-1] = 1.0

    def _perm(self, pool: int, epoch: int) -> np.ndarray:
        key = (pool, epoch)
        if key not in self._perms:
            if len(self._perms) > 4 * len(self.pools):
                self._perms.pop(min(self._perms))
            g = torch.Generator().manual_seed(self.seed * 1_000_003 + epoch + 7_919 * pool)
            self._perms[key] = self.pools[pool][torch.randperm(len(self.pools[pool]), generator=g).numpy()]
        return self._perms[key]

    def _pool_start(self, step: int) -> np.ndarray:
        """(P,) samples each pool has given before ``step``: floor(step · B · cumulative share) differences."""
        edge = np.floor(step * self.global_batch * self.cum_shares + 1e-9).astype(np.int64)
        return np.diff(edge)

    def global_indices(self, step: int) -> np.ndarray:
        """(B,) episode indices of the global batch at ``step``."""
        if len(self.pools) == 1:
            pos = step * self.global_batch + np.arange(self.global_batch)
            epochs, within = pos // len(self.eps), pos % len(self.eps)
            return np.array([self._perm(0, int(e))[i] for e, i in zip(epochs, within)], dtype=np.int64)
        start, end = self._pool_start(step), self._pool_start(step + 1)
        out = []
        for p, (a, b) in enumerate(zip(start, end)):
            pos = np.arange(a, b)
            n = len(self.pools[p])
            out += [self._perm(p, int(e))[i] for e, i in zip(pos // max(n, 1), pos % max(n, 1))]
        idx = np.array(out, dtype=np.int64)
        g = torch.Generator().manual_seed(self.seed * 1_000_003 + 104_729 * (step + 1))  # mix pools across ranks
        return idx[torch.randperm(len(idx), generator=g).numpy()]

    def indices(self, step: int, rank: int = 0, world: int = 1) -> np.ndarray:
        if self.global_batch % world:
            raise ValueError(f"batch size {self.global_batch} must be divisible by the number of processes {world}")
        b = self.global_batch // world
        return self.global_indices(step)[rank * b:(rank + 1) * b]

    def get(self, idx: np.ndarray) -> Batch:
        t = torch.from_numpy
        return Batch(self.x[t(idx)], self.actions[t(idx)], t(self.eps.unpack_grids(idx)), idx)

    def batch(self, step: int, rank: int = 0, world: int = 1) -> Batch:
        return self.get(self.indices(step, rank, world))
