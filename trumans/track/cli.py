"""`trumans track tracked.npz --scene SCENE --out out.npz`: the interaction tracker (iReplica §4).

``add_arguments`` adds the input / --out / --seed / --json options and the tracker's own
(``add_interaction_arguments``). ``trumans refine X --interactions ...``, the older spelling, is
handed here by the console script's front door (``trumans.cli``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from trumans.summary import print_summary
from trumans import argtypes
from trumans.common_args import add_device_argument

__all__ = ["add_interaction_arguments", "add_arguments", "run", "main", "tracker_scene", "TRACKER_SCENE_FORMS"]


def add_interaction_arguments(p: argparse.ArgumentParser) -> None:
    """The tracker's options (no input / --out / --seed / --json)."""
    p.add_argument("--scene", default=None,
                   help="the scene with the movable objects the hands drive: a scene folder (scene.json + meshes), "
                        "'default' (the default room) or room:SEED (a procedural room), as for `trumans sample`; "
                        "a mesh file is refused (the seats, beds and tables found in a mesh are static: nothing to "
                        "drive). Default: the scene the sequence records (a folder or room spec)")
    p.add_argument("--contact-checkpoint", action="append", default=[], metavar="[DOF=]PATH",
                   help="contact predictor (default: the shipped models/contacts.pt, one model with a class head); "
                        "repeat as DOF=PATH (DOF: slide, hinge, free) for one model per dof class")
    p.add_argument("--anchors", default=None,
                   help=".npz with 'frames' (K,) and 'xy' (K, 2): known root positions (e.g. visual localisation)")
    p.add_argument("--rigidity", type=float, default=None, help="trajectory rigidity lambda (default 1.0)")
    p.add_argument("--threshold", type=float, default=None, help="contact probability threshold (default 0.5)")
    p.add_argument("--no-correction", action="store_true", help="skip the contact-based trajectory correction")
    add_device_argument(p, runs="the contact predictor, the tracker's only network; the trajectory correction and "
                                "the objects' motion are numpy on the CPU")


def add_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.common_args import out_help

    p.add_argument("input", help="tracked sequence .npz (body motion with rotations, in the scene's frame)")
    p.add_argument("--out", required=True, help=out_help("file", "the tracked sequence .npz (corrected body + object "
                                                             "trajectories)"))
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (the tracker is deterministic; kept for the CLI contract)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")
    add_interaction_arguments(p)


TRACKER_SCENE_FORMS = "a scene folder (scene.json + meshes), 'default' or room:SEED"


def tracker_scene(arg: str | None, seq_scene: str, input_path: Path):
    """The tracker's scene (a ``trumans.scenes.Scene``) from ``--scene`` or, without it, the sequence's own
    ``scene`` entry (``trumans.scenes.spec``): a scene folder, 'default' or 'room:SEED'; a relative folder is
    tried from the current folder, then beside the input. A mesh file is refused naming the forms that
    work, before anything heavy is read."""
    from trumans.scenes.io import load_scene
    from trumans.scenes.spec import procedural_seed

    spec, given = (arg, True) if arg is not None else (seq_scene or "", False)
    if not spec:
        raise ValueError(f"no scene: the sequence records none; pass --scene ({TRACKER_SCENE_FORMS})")
    seed = procedural_seed(spec)
    if seed is not None:
        from trumans.scenes.procedural import make_room

        scene = make_room(seed)
    else:
        candidates = [Path(spec)] + ([] if Path(spec).is_absolute() else [input_path.parent / spec])
        path = next((c for c in candidates if c.exists()), None)
        where = f"--scene {spec}" if given else f"the sequence's scene {spec!r}"
        if path is None:
            error = FileNotFoundError if given else ValueError  # a recorded id (a dataset's) is no folder here
            raise error(f"{where} is not a folder here; pass --scene ({TRACKER_SCENE_FORMS})")
        if path.is_file():
            raise ValueError(f"{where} is a mesh file: the seats, beds and tables found in a mesh are static, "
                             f"so the tracker has no object to drive; give {TRACKER_SCENE_FORMS}")
        if not (path / "scene.json").is_file():
            raise FileNotFoundError(f"scene folder {path} has no scene.json; give {TRACKER_SCENE_FORMS} "
                                    f"(e.g. DATASET/scenes/<id>)")
        scene = load_scene(path)
    return scene  # static objects alone are fine: their contacts still correct the body's path (iReplica §4.2)


def _anchors(path: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    if path is None:
        return None
    from trumans.track.anchors import read_anchors

    return read_anchors(path)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from trumans.track.model_io import load_contact_models
    from trumans.sequence import load_sequence, save_sequence

    from trumans.track.interactions import TrackerConfig, track
    from trumans.out_paths import check_out, refuse_dataset_file

    check_out(args.out, "file")
    refuse_dataset_file(args.out)
    seq = load_sequence(args.input)
    scene = tracker_scene(args.scene, seq.scene, Path(args.input))
    model = load_contact_models(args.contact_checkpoint, device=args.device)
    cfg = TrackerConfig(correct=not args.no_correction)
    if args.rigidity is not None:
        cfg = replace(cfg, trajectory=replace(cfg.trajectory, rigidity=args.rigidity))
    if args.threshold is not None:
        cfg = replace(cfg, post=replace(cfg.post, threshold=args.threshold))
    res = track(seq, scene, model, cfg, anchors=_anchors(args.anchors))
    save_sequence(res.sequence, args.out)
    corr = np.linalg.norm(res.correction, axis=1)
    summary = {
        "frames": seq.num_frames, "contact_frames_left": int(res.mask[:, 0].sum()),
        "contact_frames_right": int(res.mask[:, 1].sum()), "contact_intervals": len(res.classes),
        "interactions": [{"object": it.name, "dof": it.dof, "start": it.start, "end": it.end} for it in res.interactions],
        "correction_mean_cm": float(corr.mean() * 100) if len(corr) else 0.0,
        "correction_max_cm": float(corr.max() * 100) if len(corr) else 0.0, "out": str(args.out),
        "device": str(args.device),
    }
    print(f"{len(res.interactions)} interactions ({', '.join(f'{i.name} {i.start}-{i.end}' for i in res.interactions) or 'none'}); "
          f"root corrected by {summary['correction_mean_cm']:.1f} cm on average; wrote {args.out}")
    if args.json:
        print_summary(summary)
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="trumans track", description=__doc__.splitlines()[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
