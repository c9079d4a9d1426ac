"""Input paths that must be regular files: one check, one wording for what else a path can be.

A path that names nothing is ``FileNotFoundError``; a folder, a FIFO (named pipe), a socket or a
device is ``ValueError`` saying which - never read (a FIFO blocks a reader forever, a device such as
/dev/zero never ends) and never called "missing" or "a directory" when it is something else.

JSON and TOML text read from a file or a flag goes through ``parse_json`` / ``parse_toml``: text
nesting arrays or objects deeper than ``trumans.limits.MAX_NESTING`` levels is refused before it is
parsed, with a message naming the source, its depth, the limit and the fix (Python's parsers would
recurse until they hit the interpreter's recursion limit).
"""
from __future__ import annotations

import json
import re
import stat
import tomllib
from pathlib import Path

__all__ = ["check_input_file", "file_kind", "nesting_depth", "parse_json", "parse_toml"]


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


# strings and comments, whose brackets do not nest: TOML's triple-quoted and literal strings, JSON/TOML
# basic strings (with escapes), TOML comments
_NOT_NESTING = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|#[^\n]*')
_BRACKET = re.compile(r"[\[\]{}]")


def nesting_depth(text: str, toml: bool = False) -> int:
    """The deepest nesting of ``[`` / ``{`` in JSON (or, ``toml``, TOML) ``text``, strings (and TOML
    comments) skipped; a TOML table header such as ``[[a.b]]`` counts as the brackets it has."""
    if toml:
        text = _NOT_NESTING.sub("", text)
    else:
        text = re.sub(r'"(?:\\.|[^"\\])*"', "", text)
    depth = deepest = 0
    for m in _BRACKET.finditer(text):
        if m.group() in "[{":
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth = max(0, depth - 1)
    return deepest


def _too_deep(source: str, kind: str, depth: int | None, fix: str) -> ValueError:
    from trumans.limits import MAX_NESTING

    how = f"{depth} levels" if depth is not None else "too many levels"
    return ValueError(f"{source} nests its {kind} arrays/objects {how} deep, more than the limit of {MAX_NESTING} "
                      f"(trumans.limits.MAX_NESTING); no trumans file nests that deep: {fix}")


def parse_json(text: str, source: str, fix: str = "check that it is the right file") -> object:
    """``json.loads(text)``, after refusing text nested deeper than MAX_NESTING (ValueError naming
    ``source``, e.g. 'scene.json file PATH', its depth, the limit and ``fix``). Other decoding errors
    propagate as ``json.JSONDecodeError``."""
    from trumans.limits import MAX_NESTING

    depth = nesting_depth(text)
    if depth > MAX_NESTING:
        raise _too_deep(source, "JSON", depth, fix)
    try:
        return json.loads(text)
    except RecursionError:  # not reached for depth <= MAX_NESTING; kept so no RecursionError leaks
        raise _too_deep(source, "JSON", None, fix) from None


def parse_toml(text: str, source: str, fix: str = "check that it is the right file") -> dict:
    """``tomllib.loads(text)``, after refusing text nested deeper than MAX_NESTING (as ``parse_json``).
    Other decoding errors propagate as ``tomllib.TOMLDecodeError``."""
    from trumans.limits import MAX_NESTING

    depth = nesting_depth(text, toml=True)
    if depth > MAX_NESTING:
        raise _too_deep(source, "TOML", depth, fix)
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise _too_deep(source, "TOML", None, fix) from None
