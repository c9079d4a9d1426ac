"""Dataset folders (DESIGN.md "Files"): sequences + scenes + ``index.json``.

``index.json`` holds ``name``, ``version``, ``seed``, ``fps``, ``vocabulary`` (action names),
``splits`` (``train``/``val``/``test`` -> sequence paths relative to the root), ``scenes``
(scene id -> scene folder relative to the root), ``counts`` and ``hash`` (SHA-256 of the listed
files' relative paths and bytes, so a checkpoint can name the exact data it saw).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from scenes.occupancy import OCCUPANCY_FILE, OccupancyGrid

from .sequence import Sequence, atomic_write, load_sequence

__all__ = ["INDEX_FILE", "SPLITS", "Dataset", "write_index", "content_hash"]

INDEX_FILE = "index.json"
SPLITS: tuple[str, ...] = ("train", "val", "test")
_REQUIRED = ("name", "version", "fps", "vocabulary", "splits", "scenes")


def content_hash(root: str | Path, files: list[str]) -> str:
    """SHA-256 hex digest of the relative paths ``files`` (sorted) and their bytes under ``root``."""
    root = Path(root)
    h = hashlib.sha256()
    for rel in sorted(files):
        h.update(rel.encode() + b"\0")
        with open(root / rel, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        h.update(b"\0")
    return h.hexdigest()


def write_index(root: str | Path, index: dict) -> Path:
    """Write ``index`` as ``root/index.json`` atomically (after checking its required keys)."""
    missing = [k for k in _REQUIRED if k not in index]
    if missing:
        raise ValueError(f"index lacks {missing}; a dataset index needs {list(_REQUIRED)}")
    path = Path(root) / INDEX_FILE

    def _write(tmp: str) -> None:
        with open(tmp, "w") as f:
            json.dump(index, f, indent=1, sort_keys=True)

    atomic_write(path, _write)
    return path


class Dataset:
    """Read access to a dataset folder.

    ``Dataset(root)`` reads ``root/index.json`` and checks that every listed sequence and scene
    folder exists (FileNotFoundError naming the missing ones). Sequences are numbered in the order
    train, val, test (``files``); ``load(i)`` takes that number or a path.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        path = self.root / INDEX_FILE
        if not self.root.is_dir():
            raise FileNotFoundError(f"dataset folder {self.root} does not exist; build one with `trumans data synth --out {self.root}`")
        if not path.is_file():
            raise FileNotFoundError(f"{path} does not exist; {self.root} is not a dataset folder "
                                    f"(build one with `trumans data synth --out DIR`)")
        try:
            index = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ValueError(f"{path} is not valid JSON ({e}); rebuild the dataset") from e
        if not isinstance(index, dict):
            raise ValueError(f"{path} must hold a JSON object, got {type(index).__name__}")
        missing = [k for k in _REQUIRED if k not in index]
        if missing:
            raise ValueError(f"{path} lacks {missing}; rebuild the dataset")
        splits = index["splits"]
        if not isinstance(splits, dict) or not all(isinstance(v, list) for v in splits.values()):
            raise ValueError(f"{path}: 'splits' must map split names to lists of sequence paths")
        if not isinstance(index["vocabulary"], list) or not isinstance(index["scenes"], dict):
            raise ValueError(f"{path}: 'vocabulary' must be a list and 'scenes' an object")
        self.index = index
        absent = [p for p in self.files if not p.is_file()]
        absent += [self.root / d for d in index["scenes"].values() if not (self.root / d).is_dir()]
        if absent:
            shown = ", ".join(str(a) for a in absent[:5]) + (" ..." if len(absent) > 5 else "")
            raise FileNotFoundError(f"dataset {self.root} lists {len(absent)} missing file(s)/folder(s): {shown}; "
                                    f"re-run the build (it resumes) or restore them")

    @property
    def name(self) -> str:
        return str(self.index["name"])

    @property
    def fps(self) -> float:
        return float(self.index["fps"])

    @property
    def hash(self) -> str:
        return str(self.index.get("hash", ""))

    @property
    def vocabulary(self) -> list[str]:
        """Action names, in the column order of every sequence's ``actions``."""
        return list(self.index["vocabulary"])

    @property
    def split_names(self) -> list[str]:
        """Split names in the order train, val, test (then any others, sorted)."""
        order = [s for s in SPLITS if s in self.index["splits"]]
        return order + sorted(s for s in self.index["splits"] if s not in SPLITS)

    @property
    def files(self) -> list[Path]:
        """Every sequence path, split by split in the order of ``split_names``."""
        return [self.root / p for s in self.split_names for p in self.index["splits"][s]]

    def __len__(self) -> int:
        return len(self.files)

    def split(self, name: str) -> list[Path]:
        """Absolute sequence paths of split ``name`` (e.g. 'train')."""
        if name not in self.index["splits"]:
            raise ValueError(f"unknown split {name!r}; this dataset has {self.split_names}")
        return [self.root / p for p in self.index["splits"][name]]

    def load(self, item: int | str | Path) -> Sequence:
        """A sequence by number (into ``files``) or path (absolute, or relative to the root)."""
        if isinstance(item, (int,)) and not isinstance(item, bool):
            files = self.files
            if not -len(files) <= item < len(files):
                raise IndexError(f"sequence number {item} out of range; the dataset has {len(files)}")
            return load_sequence(files[item])
        p = Path(item)
        return load_sequence(p if p.is_absolute() else self.root / p)

    @property
    def scene_ids(self) -> list[str]:
        return list(self.index["scenes"])

    def scene_dir(self, scene_id: str) -> Path:
        """The scene folder (scene.json + meshes + occupancy.npz) of ``scene_id``."""
        if scene_id not in self.index["scenes"]:
            raise KeyError(f"scene {scene_id!r} is not in this dataset; it has {len(self.index['scenes'])} "
                           f"scenes, e.g. {self.scene_ids[:3]}")
        return self.root / self.index["scenes"][scene_id]

    def occupancy(self, scene_id: str) -> OccupancyGrid:
        """The cached occupancy grid of ``scene_id`` (True = occupied)."""
        return OccupancyGrid.load(self.scene_dir(scene_id) / OCCUPANCY_FILE)

    def scene(self, scene_id: str):
        """The ``scenes.Scene`` of ``scene_id`` (meshes + objects), read from its folder."""
        from scenes.io import load_scene

        return load_scene(self.scene_dir(scene_id))
