"""Atomic file writes: readers never see a half-written file (``trumans.sequence`` re-exports it)."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["atomic_write"]


def atomic_write(path: str | Path, write_fn: Callable[[str], None]) -> None:
    """Call ``write_fn(tmp_path)`` on a temporary file beside ``path`` (parent folders are made),
    then rename it onto ``path``; on any error the temporary file is removed and nothing changes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        write_fn(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
