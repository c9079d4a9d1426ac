"""Frozen config dataclasses from plain data (a dict, as JSON gives it): the inverse of
``dataclasses.asdict``.

Keys left out keep the defaults; an unknown key, a wrong type (a number for a switch, text for a
number) or a non-finite number is a ValueError naming its path. Field types: bool, int, float, str,
Literal, tuple[str, ...], tuple[int | float, ...] (or of a fixed size), an optional (``X | None``) of
these, and nested config dataclasses. The one reader of every config in the project: the
sampler's, the HOI filter's post-steps and the training configs (``trumans.train.config``).
``set_entries`` writes the command lines' ``--set PATH=VALUE`` entries into such plain data.
"""
from __future__ import annotations

import json
import math
from dataclasses import MISSING, Field, fields, is_dataclass, replace
from types import UnionType
from typing import Any, Literal, Union, get_args, get_origin, get_type_hints

from trumans.input_files import parse_json

__all__ = ["config_from_dict", "set_entries"]


def _set_entry(text: str, roots: tuple[str, ...], example: str) -> tuple[list[str], object]:
    path, sep, value = text.partition("=")
    keys = path.strip().split(".")
    if not sep or len(keys) < 2 or keys[0] not in roots or not all(keys):
        raise ValueError(f"--set must be PATH=VALUE with PATH under {' or '.join(roots)} (like "
                         f"{example}), got {text!r}")
    try:
        return keys, parse_json(value, f"--set {path.strip()}", "give a number, true / false, \"text\" or a flat list")
    except json.JSONDecodeError:
        raise ValueError(f"--set {path}: VALUE must be JSON (a number, true / false, \"text\", [..]), got {value!r}") \
            from None


def set_entries(data: dict, texts: list[str], roots: tuple[str, ...], example: str) -> dict:
    """Write each ``PATH=VALUE`` of ``texts`` into the nested dict ``data`` (in place; returned):
    PATH is dot-separated keys starting with one of ``roots``, VALUE is JSON (``example``: one such
    entry, for the error messages). Sections are created as needed; a PATH through a value is an
    error. What the keys mean is checked later, by ``config_from_dict``."""
    for text in texts:
        keys, value = _set_entry(text, roots, example)
        node = data
        for k in keys[:-1]:
            node = node.setdefault(k, {})
            if not isinstance(node, dict):
                raise ValueError(f"--set {text!r}: {k} is a value, not a section")
        node[keys[-1]] = value
    return data


def _default(f: Field) -> Any:
    """A field's default value (MISSING when it has none)."""
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING


def _finite(value: Any, at: str) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise ValueError(f"{at} must be a finite number, got {value!r}")
    return float(value)


def _value(t: Any, value: Any, at: str) -> Any:
    """``value`` checked against field type ``t`` (not a nested config; module doc)."""
    origin, args = get_origin(t), get_args(t)
    if t is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{at} must be true or false, got {value!r}")
        return value
    if t is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise ValueError(f"{at} must be a whole number, got {value!r}")
        return value
    if t is float:
        return _finite(value, at)
    if origin is Literal:
        if value not in args:
            raise ValueError(f"{at} must be one of {list(args)}, got {value!r}")
        return value
    if t is str:
        if not isinstance(value, str):
            raise ValueError(f"{at} must be a text, got {value!r}")
        return value
    if origin is tuple and args and args[0] is str:
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise ValueError(f"{at} must be a list of names, got {value!r}")
        return tuple(value)
    if origin is tuple and args and args[0] in (int, float):
        if not isinstance(value, (list, tuple)) or (args[-1] is not Ellipsis and len(value) != len(args)):
            size = "" if args[-1] is Ellipsis else f"{len(args)} "
            kind = "whole numbers" if args[0] is int else "numbers"
            raise ValueError(f"{at} must be a list of {size}{kind}, got {value!r}")
        return tuple(_value(args[0], v, at) for v in value)
    if origin in (Union, UnionType) and len(args) == 2 and type(None) in args:  # an optional value
        return None if value is None else _value(next(a for a in args if a is not type(None)), value, at)
    raise TypeError(f"{at}: config_from_dict cannot read a field of type {t!r}")  # a bug of the config


def config_from_dict(cls: type, data: Any, where: str = "config", base: Any = None,
                     derived: dict[str, Any] | None = None):
    """An instance of config dataclass ``cls`` from ``data`` (module doc).

    base: the instance whose values the keys left out keep (default: the fields' defaults; a field
    without one must then be given). derived: the keys the data may not set because something else
    decides them, ``{key: "what sets it"}``, nested as ``{section: {key: ...}}`` for nested configs."""
    if not isinstance(data, dict):
        raise ValueError(f"{where} must be a mapping of keys to values, got {data!r}")
    derived = derived or {}
    for key in data:
        if isinstance(derived.get(key), str):
            raise ValueError(f"{where}.{key} is set by {derived[key]}, not in a config; remove it")
    hints = get_type_hints(cls)
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        shown = [k for k in known if not isinstance(derived.get(k), str)]
        raise ValueError(f"{where}: unknown key(s) {unknown}; known keys: {shown}")
    values = {}
    for key, value in data.items():
        t, at = hints[key], f"{where}.{key}"
        if is_dataclass(t):
            inner = getattr(base, key) if base is not None else _default(known[key])
            sub = derived.get(key)
            values[key] = config_from_dict(t, value, at, None if inner is MISSING else inner,
                                           sub if isinstance(sub, dict) else None)
        else:
            values[key] = _value(t, value, at)
    try:
        return replace(base, **values) if base is not None else cls(**values)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from e
