"""One writer per output folder: a lock file holding the owner's pid, and stale temp files swept.

``FolderLock(folder, command)`` takes ``folder/.trumans.lock`` with ``fcntl.flock``: the kernel
drops the lock when its owner dies (kill -9 included), so a lock left by a dead process is stale by
construction and the next writer takes it over. The file records the owner (pid, host, command,
start time) so the refusal can say who holds it.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import socket
import time
from pathlib import Path

__all__ = ["LOCK_FILE", "FolderLock", "FolderLocked", "sweep_temp_files"]

LOCK_FILE = ".trumans.lock"


class FolderLocked(RuntimeError):
    """Another live process is writing the folder."""


class FolderLock:
    """Exclusive writer lock on ``folder`` (created if missing). Use as a context manager.

    Raises ``FolderLocked`` naming the owner if another process holds it. Released (and the lock
    file removed) on exit; released by the kernel if the process dies."""

    def __init__(self, folder: str | Path, command: str) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_FILE
        self.command = command
        self._fd: int | None = None
        self.stale_owner: dict | None = None  # the owner recorded by a lock whose process died

    def acquire(self) -> "FolderLock":
        if self.folder.exists() and not self.folder.is_dir():
            raise NotADirectoryError(f"{self.folder} is a file, not a folder; choose a folder for --out")
        self.folder.mkdir(parents=True, exist_ok=True)
        for _ in range(100):
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as e:
                os.close(fd)
                if e.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    raise
                owner = _read_owner(self.path)
                who = (f"pid {owner.get('pid')} on {owner.get('host')}, `{owner.get('command')}`, since "
                       f"{owner.get('started')}" if owner else "another process")
                raise FolderLocked(f"{self.folder} is being written by {who}; wait for it to finish or "
                                   f"choose another --out (two writers would mix their outputs)") from None
            # the file we locked must still be the one at the path (a releasing owner unlinks it)
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            old = _read_owner(self.path)
            if old and old.get("pid") != os.getpid():
                self.stale_owner = old
            info = {"pid": os.getpid(), "host": socket.gethostname(), "command": self.command,
                    "started": time.strftime("%Y-%m-%d %H:%M:%S")}
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(info).encode(), 0)
            self._fd = fd
            return self
        raise FolderLocked(f"could not take the lock {self.path}; another process keeps replacing it")

    def release(self) -> None:
        if self._fd is None:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        os.close(self._fd)  # closing drops the flock
        self._fd = None

    def __enter__(self) -> "FolderLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _read_owner(path: Path) -> dict:
    try:
        from trumans.input_files import parse_json

        d = parse_json(path.read_text() or "{}", f"lock file {path}")
        return d if isinstance(d, dict) else {}
    except (OSError, ValueError):
        return {}


def sweep_temp_files(folder: str | Path) -> int:
    """Remove the temporary files and folders (``.<name>.<random>.tmp``, from ``atomic_write`` and
    ``save_scene``) that a killed writer left under ``folder``; call it only while holding the
    folder's lock (then no live writer owns them). Returns how many were removed."""
    n = 0
    for p in sorted(Path(folder).rglob(".*.tmp"), key=lambda p: len(p.parts), reverse=True):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
        else:
            p.unlink(missing_ok=True)
        n += 1
    return n
