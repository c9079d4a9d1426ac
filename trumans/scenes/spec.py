"""Scene specs: the one text form that names a scene on the command line and in a sampled sequence.

A spec is ``default`` (the default procedural room), ``room:SEED`` (a procedural room), a scene folder
(``scene.json`` + meshes) or a mesh file trimesh reads. ``trumans sample`` records the spec of the scene
it sampled in as the sequence's ``scene`` (and ``scene_up`` in its extras for a y-up mesh), so
``trumans view`` draws the same scene.
"""
from __future__ import annotations

__all__ = ["DEFAULT_ROOM_SEED", "SCENE_UP_KEY", "procedural_seed", "procedural_spec"]

DEFAULT_ROOM_SEED = 2  # the default room: a procedural room with a chair, a sofa, a bed, a table and cups
# a sequence's ``extra`` entry: the up axis of the mesh file it names as its scene ("y"; absent = z-up)
SCENE_UP_KEY = "scene_up"


def procedural_seed(spec: str | None) -> int | None:
    """'default' / '' / None -> the default room's seed, 'room:SEED' (or the older 'procedural room SEED')
    -> SEED; any other spec (a path) -> None. Raises ValueError for 'room:' without an integer seed."""
    if spec in (None, "", "default"):
        return DEFAULT_ROOM_SEED
    for prefix in ("room:", "procedural room "):
        if spec.startswith(prefix):
            tail = spec[len(prefix):]
            if not tail.lstrip("-").isdigit():
                raise ValueError(f"scene {spec!r}: write room:SEED with an integer seed, e.g. room:3")
            return int(tail)
    return None


def procedural_spec(seed: int) -> str:
    """The spec of procedural room ``seed``."""
    return f"room:{int(seed)}"
