"""Checks on what a command writes (docs/conventions.md "Output folders"), run before any heavy work.

- ``check_out(out, kind)``: an empty ``--out`` (an unset shell variable) is refused by every command;
  a run folder (``kind='folder'``) may not be the current folder or one above it; a file or stem
  output may not name an existing folder.
- ``refuse_dataset_file(path)``: a single-file output (``sample``, ``refine``, ``track``, ``view``)
  may not replace a file that a trumans dataset lists as its own (a sequence of its ``index.json``
  or an entry of its output manifest): ``sample --out DS/sequences/room_000_t00`` would silently
  change that dataset (and break its content hash).
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["check_out", "refuse_dataset_file"]


def check_out(out: str | None, kind: str, flag: str = "--out") -> None:
    """Refuse a bad ``flag`` value ``out`` (None = not given: nothing to check). ``kind``: 'folder',
    'file' or 'stem'. Raises ValueError naming the value and the fix."""
    if out is None:
        return
    if not str(out).strip():
        raise ValueError(f"{flag} is empty (an unset shell variable?); give the output {kind}")
    p = Path(out)
    if kind == "folder":
        resolved, cwd = p.resolve(), Path.cwd().resolve()
        if resolved == cwd or resolved in cwd.parents:
            raise ValueError(f"{flag} {out} is the current folder or one above it; give a new folder for the output "
                             f"(e.g. {flag} {p / 'run'})")
    elif p.is_dir() or str(out).endswith("/"):
        example = p / ("result.npz" if kind == "file" else "result")
        raise ValueError(f"{flag} {out} is a folder; give a {kind} inside it (e.g. {flag} {example})")


def refuse_dataset_file(path: str | Path, flag: str = "--out") -> None:
    """Raise FileExistsError if ``path`` is a file that a trumans dataset folder above it lists as its
    own (``trumans.dataset.listed_outputs`` or a split of its ``index.json``); links in the path are
    resolved first, so a linked folder does not hide the dataset."""
    from trumans.dataset import CLAIM_FILE, INDEX_FILE, listed_outputs

    target = Path(path).resolve()
    for root in target.parents:
        if not ((root / INDEX_FILE).is_file() or (root / CLAIM_FILE).is_file()):
            continue
        rel = target.relative_to(root).as_posix()
        try:
            owned = set(listed_outputs(root))
        except (OSError, ValueError):
            owned = set()
        if rel in owned:
            raise FileExistsError(f"{flag} {path} would replace {rel}, a file of the trumans dataset {root}; "
                                  f"writing it would change that dataset: choose an {flag} outside it")
