"""Atomic file writes: readers never see a half-written file (``trumans.sequence`` re-exports it)."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["atomic_write", "umask_mode"]


def umask_mode(mode: int) -> int:
    """``mode`` (e.g. 0o666 for files, 0o777 for folders) less the process's umask: the permissions
    ``open`` / ``mkdir`` would give, which ``tempfile``'s private 0600 / 0700 do not."""
    mask = os.umask(0)
    os.umask(mask)
    return mode & ~mask


def atomic_write(path: str | Path, write_fn: Callable[[str], None]) -> None:
    """Call ``write_fn(tmp_path)`` on a temporary file beside ``path`` (parent folders are made),
    then rename it onto ``path``; on any error the temporary file is removed and nothing changes."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        write_fn(tmp)
        os.chmod(tmp, umask_mode(0o666))
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
