"""FBX animation curves: 6.x ``Takes`` channel keys and 7.x ``AnimationCurve`` / ``AnimationCurveNode``
objects, read into ``FbxModel.curves`` as ``{(property, axis): (times_s, values, constant)}``."""
from __future__ import annotations

import numpy as np

from .fbx_nodes import FbxNode

FBX_TICKS = 46_186_158_000  # FBX time units per second
_CHANNEL_PROP = {"T": "Lcl Translation", "R": "Lcl Rotation", "S": "Lcl Scaling"}


_INTERP = {"L", "C", "U"}


def _keys_v6(vals: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """6.x ``Key:`` list -> times (s), values, constant flags. Entries are ``time, value, interp``
    followed by interpolation data (``C,n`` / ``U,s,slope,slope,n`` ...), skipped here."""
    if len(vals) == 1 and isinstance(vals[0], np.ndarray):  # no interpolation letters at all
        a = vals[0].reshape(-1, 2)
        return a[:, 0] / FBX_TICKS, a[:, 1], np.zeros(len(a), bool)
    t, v, c = [], [], []
    i, n = 0, len(vals)
    while i + 1 < n:
        t.append(vals[i])
        v.append(vals[i + 1])
        interp = vals[i + 2] if i + 2 < n and isinstance(vals[i + 2], str) else "L"
        c.append(interp == "C")
        i += 3 if i + 2 < n and isinstance(vals[i + 2], str) else 2
        # skip interpolation data up to the next "number, number, letter-in-L/C/U" (or the end)
        while i < n and not (not isinstance(vals[i], str) and i + 1 < n and not isinstance(vals[i + 1], str)
                             and (i + 2 >= n or vals[i + 2] in _INTERP)):
            i += 1
    return np.asarray(t, np.float64) / FBX_TICKS, np.asarray(v, np.float64), np.asarray(c, bool)


def curves_v6(takes: FbxNode | None, key_of: dict, models: list) -> None:
    """Fill ``models[k].curves`` from the 6.x ``Takes`` (the current take, else the first)."""
    if takes is None:
        return
    all_takes = takes.find_all("Take")
    if not all_takes:
        return
    cur = takes.find("Current")
    take = next((t for t in all_takes if cur is not None and cur.props and t.props and t.props[0] == cur.props[0]),
                all_takes[0])
    for mn in take.find_all("Model"):
        k = key_of.get(mn.props[0] if mn.props else None)
        if k is None:
            continue
        tr = next((c for c in mn.find_all("Channel") if c.props and c.props[0] == "Transform"), None)
        if tr is None:
            continue
        for ch in tr.find_all("Channel"):
            prop = _CHANNEL_PROP.get(ch.props[0] if ch.props else "")
            if prop is None:
                continue
            for ax in ch.find_all("Channel"):
                axis = "XYZ".find(str(ax.props[0])) if ax.props else -1
                key = ax.find("Key")
                if axis < 0:
                    continue
                if key is None or not key.props:
                    d = ax.find("Default")
                    if d is not None and d.props:  # an unkeyed channel holds its default
                        models[k].props[prop] = models[k].props[prop].copy()
                        models[k].props[prop][axis] = float(d.props[0])
                    continue
                models[k].curves[(prop, axis)] = _keys_v6(key.props)


def curves_v7(objects: FbxNode, links: list, key_of: dict, models: list, vec_props: tuple[str, ...]) -> None:
    """Fill ``models[k].curves`` from 7.x AnimationCurve(Node)s of the first AnimationStack."""
    curves = {}
    for n in objects.find_all("AnimationCurve"):
        kt, kv = n.find("KeyTime"), n.find("KeyValueFloat")
        if kt is None or kv is None or not kt.props or not kv.props:
            continue
        t = np.asarray(kt.props[0], np.float64).ravel() / FBX_TICKS
        v = np.asarray(kv.props[0], np.float64).ravel()
        flags = n.find("KeyAttrFlags")
        refs = n.find("KeyAttrRefCount")
        const = np.zeros(len(t), bool)
        if flags is not None and refs is not None and flags.props and refs.props:
            f = np.repeat(np.asarray(flags.props[0], np.int64).ravel(), np.asarray(refs.props[0], np.int64).ravel())
            if len(f) == len(t):
                const = (f & 0x02) != 0
        curves[n.props[0]] = (t, v, const)
    cnodes = {n.props[0]: n for n in objects.find_all("AnimationCurveNode")}
    stacks = [n.props[0] for n in objects.find_all("AnimationStack")]
    allowed = None
    if stacks:  # only the curve nodes of the first stack's layers
        layers = {c for c, p, prop in links if p == stacks[0] and prop is None}
        allowed = {c for c, p, prop in links if p in layers and prop is None and c in cnodes}
    target = {}  # curve node -> (model, property)
    for c, p, prop in links:
        if c in cnodes and p in key_of and prop in vec_props and (allowed is None or c in allowed):
            target[c] = (key_of[p], prop)
    for c, p, prop in links:
        if c in curves and p in target and prop in ("d|X", "d|Y", "d|Z"):
            k, vec = target[p]
            models[k].curves[(vec, "XYZ".index(prop[-1]))] = curves[c]
