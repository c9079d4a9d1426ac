"""One-call Python API: generate a motion in a scene, refine a tracked sequence, track its interactions.

    import trumans
    seq = trumans.generate(plan=[{"do": "goto", "to": [2.4, 3.0]}], scene="default", seed=0)
    clean = trumans.refine_tracked("tracked.npz")             # the HOI filter (I'm-HOI §3.2)
    driven = trumans.track_interactions(seq_with_rotations, "data/synth/scenes/room_000")  # iReplica §4

Each function is the library call behind its command (``trumans sample``, ``trumans refine``,
``trumans track``) without the files: it returns a ``trumans.Sequence`` and writes
nothing (``trumans.save_sequence`` or ``trumans.viz.export.export`` write one).
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from trumans.sequence import Sequence, load_sequence

__all__ = ["generate", "refine_tracked", "track_interactions"]


def generate(plan=None, scene: str | Path = "default", *, seed: int = 0, checkpoint: str | Path | None = None,
             config=None, start: tuple[float, float] | None = None, heading: float | None = None,
             body: np.ndarray | None = None, up: str = "z", device: str = "cpu", max_seconds: float = 600.0,
             progress: bool = False) -> Sequence:
    """Sample one long motion (TRUMANS §4) of ``plan`` in ``scene``, as ``trumans sample`` does.

    plan: None (the default plan: sit, stand up, walk, drink, walk back), a plan dict / list of step
    dicts (docs/generate.md "Plans"), a ``Plan`` or a .json/.toml path. scene: 'default', 'room:SEED', a
    scene folder or a mesh file (``up`` 'y' for a y-up mesh). config: a ``SamplerConfig`` (default: the
    command's defaults). start (x, y) m / heading rad override the plan's. body: a standing body's joints
    (24, 3) m whose bone lengths are kept. Returns the sequence: joints (T, 24, 3) world m at the
    checkpoint's fps, action labels, carried objects' tracks, ``scene`` = the scene's spec; its figures
    are those of ``trumans sample --json`` (use ``trumans.sample.generate.generate_sequences`` for them)."""
    from trumans.sample.generate import generate_sequences

    return generate_sequences(plan, scene, checkpoint=checkpoint, seed=seed, num_samples=1, config=config,
                              start=start, heading=heading, body=body, up=up, device=device,
                              max_seconds=max_seconds, progress=progress).sequences[0]


@lru_cache(maxsize=4)
def _filter(path: str | None, device: str = "cpu"):
    from trumans.refine.pipeline import HOIFilter

    return HOIFilter.load(path, device=device)


def _device(device: str) -> str:
    """``device`` checked as ``--device`` is (cpu, cuda, cuda:N that this machine has): ValueError otherwise."""
    import argparse

    from trumans import argtypes

    try:
        return argtypes.device(str(device))
    except argparse.ArgumentTypeError as e:
        raise ValueError(f"device {e}") from None


def refine_tracked(seq: Sequence | str | Path, *, category: str | None = None, object_name: str | None = None,
                   checkpoint: str | Path | None = None, options=None, device: str = "cpu") -> Sequence:
    """Refine a tracked human-object sequence with the HOI filter (I'm-HOI §3.2), as ``trumans refine`` does.

    seq: a ``Sequence`` or an .npz path (joints (T, 24, 3) m, optional rotations, one object's pose, NaN =
    missing; format in docs/refine.md); category / object_name: the object's, when the sequence does not
    say; checkpoint: the filter (default the shipped models/refine.pt, loaded once per process);
    options: ``trumans.refine.pipeline.RefineOptions``; device: where the filter network runs (cpu, cuda,
    cuda:N). Returns the refined sequence (same frames and fps)."""
    from trumans.refine.pipeline import RefineOptions

    device = _device(device)
    if not isinstance(seq, Sequence):
        seq = load_sequence(seq, allow_missing=True)
    out, _ = _filter(None if checkpoint is None else str(checkpoint), device).refine_sequence(
        seq, category=category, object_name=object_name, options=options or RefineOptions())
    return out


def track_interactions(seq: Sequence | str | Path, scene, *, contact_checkpoints: list[str] | None = None,
                       config=None, anchors: tuple[np.ndarray, np.ndarray] | None = None,
                       device: str = "cpu") -> Sequence:
    """Track a body's interactions with a scene's objects (iReplica §4.1-4.3), as ``trumans track``
    does: contacts predicted from the pose, the root path corrected by them, objects driven by the
    hands within their degrees of freedom.

    seq: a ``Sequence`` or .npz path with ``rotations`` (T, 24, 6) and joints in the scene's frame; scene:
    a ``trumans.scenes.Scene`` or a spec as ``trumans track --scene`` takes (a scene folder, 'default',
    room:SEED); contact_checkpoints: as ``--contact-checkpoint`` (default the shipped models/contacts.pt);
    config: ``trumans.track.interactions.TrackerConfig``; anchors: (frames (K,), root xy (K, 2) m) known
    positions; device: where the contact predictor (the tracker's only network) runs. Returns the corrected
    body with the objects' trajectories (``trumans.track.interactions.track`` gives the contacts too)."""
    from trumans.scenes.scene import Scene
    from trumans.track.cli import tracker_scene
    from trumans.track.interactions import TrackerConfig, track
    from trumans.track.model_io import load_contact_models

    device = _device(device)
    if not isinstance(seq, Sequence):
        seq = load_sequence(seq)
    if not isinstance(scene, Scene):
        scene = tracker_scene(str(scene), "", Path("."))
    model = load_contact_models(contact_checkpoints, device=device)
    return track(seq, scene, model, config or TrackerConfig(), anchors=anchors).sequence
