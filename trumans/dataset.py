"""Dataset folders (docs/conventions.md "File formats"): sequences + scenes + ``index.json``.

``index.json`` holds ``name``, ``version``, ``seed``, ``fps``, ``vocabulary`` (action names),
``splits`` (``train``/``val``/``test`` -> sequence paths relative to the root), ``scenes``
(scene id -> scene folder relative to the root), ``counts`` and ``hash`` (SHA-256 of the listed
files' relative paths and bytes, so a checkpoint can name the exact data it saw).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import stat
from collections.abc import Iterable
from pathlib import Path, PurePosixPath

from trumans.input_files import file_kind, parse_json
from trumans.scenes.occupancy import OCCUPANCY_FILE, OccupancyGrid

from .sequence import Sequence, atomic_write, load_sequence

__all__ = ["INDEX_FILE", "OUTPUTS_FILE", "SPLITS", "Dataset", "DatasetWriter", "load_index", "write_index",
           "content_hash", "record_outputs", "listed_outputs"]

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


def _bad(path: Path, what: str) -> ValueError:
    return ValueError(f"{path}: {what}; repair the file or rebuild the dataset")


def _rel_path(path: Path, field: str, p: object) -> str:
    """A path inside the dataset folder: relative, no '..'."""
    if not isinstance(p, str) or not p:
        raise _bad(path, f"{field} must hold relative paths (text), got {p!r}")
    parts = PurePosixPath(p).parts
    if PurePosixPath(p).is_absolute() or ".." in parts:
        raise _bad(path, f"{field} path {p!r} leaves the dataset folder; paths must be relative and inside it")
    return p


def load_index(root: str | Path) -> dict:
    """Read and type-check ``root/index.json``: name (text), fps (positive number), vocabulary
    (list of text), splits (split -> list of relative sequence paths), scenes (id -> relative
    folder). Raises FileNotFoundError / ValueError naming the field and the fix."""
    root = Path(root)
    path = root / INDEX_FILE
    if not root.is_dir():
        if file_kind(root) is not None:
            raise ValueError(f"dataset folder {root} is a {file_kind(root)}, not a folder; pass a dataset folder "
                             f"(with index.json)")
        raise FileNotFoundError(f"dataset folder {root} does not exist; build one with `trumans data synth --out {root}`")
    if not path.is_file():
        raise FileNotFoundError(f"{path} does not exist; {root} is not a dataset folder "
                                f"(build one with `trumans data synth --out DIR`)")
    try:
        index = parse_json(path.read_text(), f"dataset index {path}", "rebuild the dataset")
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path} is not valid JSON ({e}); rebuild the dataset") from e
    if not isinstance(index, dict):
        raise ValueError(f"{path} must hold a JSON object, got {type(index).__name__}; rebuild the dataset")
    missing = [k for k in _REQUIRED if k not in index]
    if missing:
        raise ValueError(f"{path} lacks {missing}; rebuild the dataset")
    if not isinstance(index["name"], str):
        raise _bad(path, f"'name' must be text, got {index['name']!r}")
    fps = index["fps"]
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not (math.isfinite(fps) and fps > 0):
        raise _bad(path, f"'fps' must be a positive number, got {fps!r}")
    vocab = index["vocabulary"]
    if not isinstance(vocab, list) or not all(isinstance(v, str) for v in vocab):
        raise _bad(path, f"'vocabulary' must be a list of action names (text), got {str(vocab)[:80]}")
    splits = index["splits"]
    if not isinstance(splits, dict) or not all(isinstance(v, list) for v in splits.values()):
        raise _bad(path, "'splits' must map split names to lists of sequence paths")
    for name, files in splits.items():
        for p in files:
            _rel_path(path, f"'splits'/{name}", p)
    scenes = index["scenes"]
    if not isinstance(scenes, dict):
        raise _bad(path, f"'scenes' must map scene ids to folders, got {type(scenes).__name__}")
    for sid, d in scenes.items():
        _rel_path(path, f"'scenes'/{sid}", d)
    return index


class Dataset:
    """Read access to a dataset folder.

    ``Dataset(root)`` reads ``root/index.json`` and checks that every listed sequence and scene
    folder exists (FileNotFoundError naming the missing ones). Sequences are numbered in the order
    train, val, test (``files``); ``load(i)`` takes that number or a path.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root).absolute()  # split paths are absolute, so `load` of one never joins the root twice
        self.index = load_index(self.root)
        absent = [p for p in self.files if not p.is_file()]
        absent += [self.root / d for d in self.index["scenes"].values() if not (self.root / d).is_dir()]
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
            raise ValueError(f"scene {scene_id!r} is not in this dataset ({self.root}); it has {len(self.index['scenes'])} "
                           f"scenes, e.g. {self.scene_ids[:3]}; the sequence names a scene its index lacks")
        return self.root / self.index["scenes"][scene_id]

    def occupancy(self, scene_id: str) -> OccupancyGrid:
        """The cached occupancy grid of ``scene_id`` (True = occupied)."""
        return OccupancyGrid.load(self.scene_dir(scene_id) / OCCUPANCY_FILE)

    def scene(self, scene_id: str):
        """The ``trumans.scenes.Scene`` of ``scene_id`` (meshes + objects), read from its folder."""
        from trumans.scenes.io import load_scene

        return load_scene(self.scene_dir(scene_id))


CLAIM_FILE = ".trumans-output.json"
NOT_OURS = "holds no trumans output"
# the output manifest: every file a dataset writer (synth, augment, the importers) wrote, one path
# relative to the folder a line, appended *before* the file is written (so a killed run's files are
# listed too); --overwrite removes exactly these files and nothing else
OUTPUTS_FILE = ".trumans-outputs.txt"
# the top-level files of a dataset folder (an older output without the manifest: see ``_derived_outputs``)
_TOP_FILES = (INDEX_FILE, "manifest.json", "summary.json", "summary.png")


def _inside(rel: object) -> str | None:
    """``rel`` if it is a non-empty relative path with no '..' (a path that stays inside the folder), else None."""
    if not isinstance(rel, str) or not rel.strip() or "\0" in rel:
        return None
    pp = PurePosixPath(rel)
    if pp.is_absolute() or ".." in pp.parts or not pp.parts or pp.parts == (".",):
        return None
    return pp.as_posix()


def record_outputs(root: str | Path, rels: Iterable[str]) -> None:
    """Append ``rels`` (paths relative to the dataset folder ``root``) to its output manifest
    ``OUTPUTS_FILE``. Call it *before* writing those files, from the writer or its workers (one
    ``O_APPEND`` write per call, so concurrent workers do not interleave lines). The manifest is
    never written through a link (``O_NOFOLLOW``). Raises ValueError for a path leaving ``root``."""
    lines = []
    for r in rels:
        ok = _inside(r)
        if ok is None or "\n" in r:
            raise ValueError(f"output path {r!r} is not a relative path inside {root}; this is a bug")
        lines.append(ok + "\n")
    if not lines:
        return
    data = "".join(lines).encode()
    fd = os.open(Path(root) / OUTPUTS_FILE, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o666)
    try:
        while data:
            data = data[os.write(fd, data):]
    finally:
        os.close(fd)


def _read_json(path: Path) -> object:
    try:
        if path.is_symlink() or not path.is_file():
            return None
        return json.loads(path.read_text())
    except (OSError, ValueError, RecursionError):
        return None


def _derived_outputs(root: Path) -> set[str]:
    """The outputs of a dataset folder written before the output manifest existed (or of a dataset
    with an ``index.json`` but no claim), derived from what it lists: the top-level files, every
    sequence of ``index.json``'s splits, every scene folder's ``scene.json``, the meshes it names
    and ``occupancy.npz``, the room records ``rooms/<id>.json`` of its scenes and, from
    ``manifest.json`` (augment), every output sequence and scene and ``records/<source stem>.json``."""
    files: set[str] = set(_TOP_FILES)
    index = _read_json(root / INDEX_FILE)
    index = index if isinstance(index, dict) else {}
    splits = index.get("splits") if isinstance(index.get("splits"), dict) else {}
    scenes = index.get("scenes") if isinstance(index.get("scenes"), dict) else {}
    seqs = [p for v in splits.values() if isinstance(v, list) for p in v]
    scene_dirs = list(scenes.values())
    manifest = _read_json(root / "manifest.json")
    outputs = manifest.get("outputs") if isinstance(manifest, dict) else None
    for o in outputs if isinstance(outputs, list) else []:
        if isinstance(o, dict):
            seqs.append(o.get("sequence"))
            scene_dirs.append(o.get("scene_dir"))
            if isinstance(o.get("source"), str):
                files.add(f"records/{PurePosixPath(o['source']).stem}.json")
    files.update(r for r in map(_inside, seqs) if r)
    for d in filter(None, map(_inside, scene_dirs)):
        files.update({f"{d}/scene.json", f"{d}/occupancy.npz", f"rooms/{PurePosixPath(d).name}.json"})
        doc = _read_json(root / d / "scene.json")
        for key in ("static", "objects"):
            entries = doc.get(key) if isinstance(doc, dict) else None
            for e in entries if isinstance(entries, list) else []:
                mesh = _inside(e.get("mesh")) if isinstance(e, dict) else None
                if mesh:
                    files.add(f"{d}/{mesh}")
    return files


def listed_outputs(root: str | Path) -> list[str]:
    """The files (relative paths, sorted) that ``--overwrite`` may remove from the trumans output
    ``root``: those its output manifest lists (``_derived_outputs`` for an older output without
    one), plus the claim and the manifest themselves. Lines that would leave ``root`` are ignored."""
    root = Path(root)
    ledger = root / OUTPUTS_FILE
    if ledger.is_file() and not ledger.is_symlink():
        files = {r for r in map(_inside, ledger.read_text(errors="replace").splitlines()) if r}
    else:
        files = _derived_outputs(root)
    return sorted(files | {CLAIM_FILE, OUTPUTS_FILE})


def _remove_outputs(root: Path) -> int:
    """Delete the files ``listed_outputs(root)`` names, then the folders that became empty; returns
    the number of files removed. Only regular files are deleted: a listed path that is now a link or
    a folder, or that is reached through a linked folder, is left alone (links are never followed),
    and a folder still holding anything (a user's file) stays."""
    removed, parents = 0, set()
    for rel in listed_outputs(root):
        parts = PurePosixPath(rel).parts
        d, through_link = root, False
        for part in parts[:-1]:
            d = d / part
            if d.is_symlink() or not d.is_dir():
                through_link = True
                break
        if through_link:
            continue
        path = d / parts[-1]
        try:
            if not stat.S_ISREG(os.lstat(path).st_mode):
                continue
        except OSError:
            continue
        path.unlink()
        removed += 1
        parents.update(root.joinpath(*parts[:i]) for i in range(1, len(parts)))
    for d in sorted(parents, key=lambda p: len(p.parts), reverse=True):
        try:
            os.rmdir(d)  # only an empty folder (never a link: rmdir refuses one)
        except OSError:
            pass
    return removed


class DatasetWriter:
    """The one writer of a dataset folder (synth, augment, importers).

    ``with DatasetWriter(root, command, settings, overwrite) as w:`` takes the folder's lock
    (``trumans.io_lock.FolderLock``: a second writer is refused), then claims the folder:
    a new or empty folder, or one claimed by the same command with the same ``settings``
    (a resume), is accepted; a folder holding other data (another dataset's ``index.json``, the
    output of other settings) is refused unless ``overwrite``, which first removes the previous
    outputs: exactly the files its output manifest (``OUTPUTS_FILE``) lists, then the folders they
    leave empty; a file of the user's inside ``sequences/`` stays, and links are never followed
    (``_remove_outputs``). A folder of files that are no trumans output is refused even with
    ``overwrite``, and so are an empty ``root`` and the current folder or one above it.
    Every file written into the folder is recorded first (``record``, or ``record_outputs`` from a
    worker). Stale temp files of killed writers are swept. ``save_occupancy`` writes a scene grid through
    ``OccupancyGrid``; ``finish(index)`` adds the content hash and writes ``index.json``.
    Call it after every input is validated: a refused run changes nothing on disk, and a run that
    fails before writing any sequence removes the folder if it made it."""

    def __init__(self, root: str | Path, command: str, settings: dict, overwrite: bool = False) -> None:
        if not str(root).strip():
            raise ValueError("--out is empty (an unset shell variable?); give the output folder")
        resolved, cwd = Path(root).resolve(), Path.cwd().resolve()
        if resolved == cwd or resolved in cwd.parents:
            raise ValueError(f"--out {root} is the current folder or one above it; give a new or empty folder "
                             f"for the output (e.g. --out {Path(root) / 'out'})")
        self.root = Path(root)
        self.command = command
        self.settings = json.loads(json.dumps(settings, sort_keys=True, default=str))
        self.overwrite = overwrite
        self._lock = None
        self._created = False
        self.resumed = False
        self.swept = 0
        self.removed = 0  # files of a previous output removed by --overwrite

    def __enter__(self) -> "DatasetWriter":
        from .io_lock import LOCK_FILE, FolderLock, sweep_temp_files

        if self.root.exists() and not self.root.is_dir():
            raise NotADirectoryError(f"{self.root} is a file; give --out a folder (new or empty)")
        existed = self.root.is_dir()
        self._created = not existed
        self._lock = FolderLock(self.root, f"trumans {self.command}").acquire()
        try:
            content = sorted(p.name for p in self.root.iterdir() if p.name != LOCK_FILE) if existed else []
            refusal = self._refusal(content)
            if refusal and (not self.overwrite or refusal.endswith(NOT_OURS)):
                fix = ("choose another --out (--overwrite replaces only a trumans output)" if refusal.endswith(NOT_OURS)
                       else "pass --overwrite to replace it, or choose another --out")
                raise FileExistsError(f"{self.root} {refusal}; {fix}")
            self.removed = _remove_outputs(self.root) if refusal else 0
            self.resumed = bool(content) and not refusal
            self.swept = sweep_temp_files(self.root)
            claim = {"command": self.command, "settings": self.settings}
            atomic_write(self.root / CLAIM_FILE, lambda tmp: Path(tmp).write_text(json.dumps(claim, indent=1)))
        except BaseException:
            self._lock.release()
            self._lock = None
            if not existed:
                shutil.rmtree(self.root, ignore_errors=True)
            raise
        return self

    def _refusal(self, content: list[str]) -> str:
        """Why the folder is not ours to write ('' if it is)."""
        if not content:
            return ""
        claim_path = self.root / CLAIM_FILE
        if claim_path.is_file():
            try:
                claim = json.loads(claim_path.read_text())
            except (ValueError, OSError):
                claim = None
            if not isinstance(claim, dict):
                return f"holds an unreadable {CLAIM_FILE}"
            if claim.get("command") != self.command:
                return f"holds the output of `trumans {claim.get('command')}`"
            if claim.get("settings") != self.settings:
                old = claim.get("settings") if isinstance(claim.get("settings"), dict) else {}
                diff = [f"{k}: {old.get(k)!r} -> {self.settings.get(k)!r}"
                        for k in sorted(set(old) | set(self.settings)) if old.get(k) != self.settings.get(k)]
                return (f"holds the output of `trumans {self.command}` with other settings "
                        f"({'; '.join(diff)[:300]}); re-run with the same settings to resume it")
            return ""
        if INDEX_FILE in content:
            try:
                name = json.loads((self.root / INDEX_FILE).read_text()).get("name", "?")
            except (ValueError, OSError, AttributeError):
                name = "?"
            return f"holds another dataset ({name!r}) that this run would overwrite"
        shown = ", ".join(content[:4]) + (" ..." if len(content) > 4 else "")
        return f"is not empty ({shown}) and {NOT_OURS}"

    def __exit__(self, *exc) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None
        # a failed run that made the folder and wrote no sequence leaves the disk as it was (nothing to resume)
        seqs = self.root / "sequences"
        if exc[0] is not None and self._created and not (seqs.is_dir() and any(seqs.iterdir())):
            shutil.rmtree(self.root, ignore_errors=True)

    def record(self, *rels: str) -> None:
        """Record files (relative to the root) as this run's outputs before writing them (``record_outputs``)."""
        record_outputs(self.root, rels)

    def save_occupancy(self, scene_id: str, grid: OccupancyGrid) -> str:
        """Write ``scenes/<scene_id>/occupancy.npz``; returns the scene folder relative to the root."""
        rel = f"scenes/{scene_id}"
        self.record(f"{rel}/{OCCUPANCY_FILE}")
        grid.save(self.root / rel / OCCUPANCY_FILE)
        return rel

    def finish(self, index: dict) -> str:
        """Hash the listed sequences, write ``index.json`` (``index`` gains ``hash``); returns the hash."""
        files = [p for s in index.get("splits", {}).values() for p in s]
        if not files:
            raise ValueError(f"no sequences to write into {self.root}; the inputs hold no usable motion")
        index["hash"] = content_hash(self.root, files)
        self.record(INDEX_FILE)
        write_index(self.root, index)
        load_index(self.root)  # what we wrote must read back
        return index["hash"]
