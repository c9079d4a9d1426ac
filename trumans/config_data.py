"""Frozen config dataclasses from plain data (a dict, as JSON gives it): the inverse of
``dataclasses.asdict`` for the sampler's configs (``SamplerConfig.from_dict``) and the HOI filter's
post-steps (``PostStepsConfig.from_dict``).

Keys left out keep the defaults; an unknown key, a wrong type (a number for a switch, text for a
number) or a non-finite number is a ValueError naming its path. Field types: bool, int, float,
tuple[str, ...] and nested config dataclasses. ``set_entries`` writes the command lines' ``--set
PATH=VALUE`` entries into such plain data.
"""
from __future__ import annotations

import json
import math
from dataclasses import fields, is_dataclass, replace
from typing import Any, Literal, get_args, get_origin, get_type_hints

__all__ = ["config_from_dict", "set_entries"]


def _set_entry(text: str, roots: tuple[str, ...], example: str) -> tuple[list[str], object]:
    path, sep, value = text.partition("=")
    keys = path.strip().split(".")
    if not sep or len(keys) < 2 or keys[0] not in roots or not all(keys):
        raise ValueError(f"--set must be PATH=VALUE with PATH under {' or '.join(roots)} (like "
                         f"{example}), got {text!r}")
    try:
        return keys, json.loads(value)
    except (json.JSONDecodeError, RecursionError):
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


def config_from_dict(cls: type, data: Any, where: str = "config", base: Any = None):
    """An instance of config dataclass ``cls`` from ``data`` (module doc); ``base``: the instance
    whose values the keys left out keep (default ``cls()``)."""
    if not isinstance(data, dict):
        raise ValueError(f"{where} must be a mapping of keys to values, got {data!r}")
    base = cls() if base is None else base
    hints = get_type_hints(cls)
    known = [f.name for f in fields(cls)]
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown}; known keys: {known}")
    values = {}
    for key, value in data.items():
        t, at = hints[key], f"{where}.{key}"
        if is_dataclass(t):
            values[key] = config_from_dict(t, value, at, getattr(base, key))
        elif t is bool:
            if not isinstance(value, bool):
                raise ValueError(f"{at} must be true or false, got {value!r}")
            values[key] = value
        elif t is int:
            if not isinstance(value, int) or isinstance(value, bool):
                raise ValueError(f"{at} must be a whole number, got {value!r}")
            values[key] = value
        elif t is float:
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ValueError(f"{at} must be a finite number, got {value!r}")
            values[key] = float(value)
        elif get_origin(t) is Literal:
            if value not in get_args(t):
                raise ValueError(f"{at} must be one of {list(get_args(t))}, got {value!r}")
            values[key] = value
        elif t is str:
            if not isinstance(value, str):
                raise ValueError(f"{at} must be a text, got {value!r}")
            values[key] = value
        elif get_origin(t) is tuple and get_args(t)[0] is str:
            if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{at} must be a list of names, got {value!r}")
            values[key] = tuple(value)
        else:  # a field type this reader does not know: a bug of the config, not of the data
            raise TypeError(f"{at}: config_from_dict cannot read a field of type {t!r}")
    try:
        return replace(base, **values)
    except ValueError as e:
        raise ValueError(f"{where}: {e}") from e
