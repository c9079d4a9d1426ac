"""Input paths that must be regular files: one check, one wording for what else a path can be.

A path that names nothing is ``FileNotFoundError``; a folder, a FIFO (named pipe), a socket or a
device is ``ValueError`` saying which - never read (a FIFO blocks a reader forever, a device such as
/dev/zero never ends) and never called "missing" or "a directory" when it is something else.
"""
from __future__ import annotations

import stat
from pathlib import Path

__all__ = ["check_input_file", "file_kind"]


def file_kind(path: str | Path) -> str | None:
    """What ``path`` is (links followed): 'file', 'folder', 'FIFO (named pipe)', 'socket', 'device',
    or None when nothing is there."""
    try:
        mode = Path(path).stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        return None
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISDIR(mode):
        return "folder"
    if stat.S_ISFIFO(mode):
        return "FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "device"


def check_input_file(path: str | Path, what: str, fix: str = "") -> Path:
    """``path`` as a Path when it is a regular file; otherwise FileNotFoundError ("{what} {path} does
    not exist") or ValueError ("{what} {path} is a folder / FIFO / device, not a file"), each
    followed by ``fix`` (what to pass instead) when given. Reads nothing."""
    path = Path(path)
    kind = file_kind(path)
    tail = f"; {fix}" if fix else ""
    if kind is None:
        raise FileNotFoundError(f"{what} {path} does not exist{tail}")
    if kind != "file":
        raise ValueError(f"{what} {path} is a {kind}, not a file{tail}")
    return path
