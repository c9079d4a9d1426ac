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

__all__ = ["add_interaction_arguments", "add_arguments", "run", "main"]


def add_interaction_arguments(p: argparse.ArgumentParser) -> None:
    """The tracker's options (no input / --out / --seed / --json)."""
    p.add_argument("--scene", default=None,
                   help="scene folder (scene.json + meshes) with the interactable objects; default: the sequence's "
                        "'scene' entry when it is a folder")
    p.add_argument("--contact-checkpoint", action="append", default=[], metavar="[DOF=]PATH",
                   help="contact predictor (default: the shipped models/contacts.pt, one model with a class head); "
                        "repeat as DOF=PATH (DOF: slide, hinge, free) for one model per dof class")
    p.add_argument("--anchors", default=None,
                   help=".npz with 'frames' (K,) and 'xy' (K, 2): known root positions (e.g. visual localisation)")
    p.add_argument("--rigidity", type=float, default=None, help="trajectory rigidity lambda (default 1.0)")
    p.add_argument("--threshold", type=float, default=None, help="contact probability threshold (default 0.5)")
    p.add_argument("--no-correction", action="store_true", help="skip the contact-based trajectory correction")


def add_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.common_args import out_help

    p.add_argument("input", help="tracked sequence .npz (body motion with rotations, in the scene's frame)")
    p.add_argument("--out", required=True, help=out_help("file", "the tracked sequence .npz (corrected body + object "
                                                             "trajectories)"))
    p.add_argument("--seed", type=argtypes.seed, default=0, help="random seed (the tracker is deterministic; kept for the CLI contract)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object on the last line")
    add_interaction_arguments(p)


def _scene_folder(arg: str | None, seq_scene: str, input_path: Path) -> Path:
    if arg is not None:
        folder = Path(arg)
    elif seq_scene and (Path(seq_scene).is_dir() or (input_path.parent / seq_scene).is_dir()):
        folder = Path(seq_scene) if Path(seq_scene).is_dir() else input_path.parent / seq_scene
    else:
        raise ValueError(f"no scene: pass --scene FOLDER (the sequence names scene {seq_scene!r}, which is not a folder)")
    if not (folder / "scene.json").is_file():
        raise FileNotFoundError(f"scene folder {folder} has no scene.json; pass a scene folder written by trumans "
                                f"(e.g. DATASET/scenes/<id>)")
    return folder


def _anchors(path: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    if path is None:
        return None
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"anchors file {p} does not exist")
    with np.load(p, allow_pickle=False) as z:
        if "frames" not in z.files or "xy" not in z.files:
            raise ValueError(f"{p} must hold 'frames' (K,) and 'xy' (K, 2); it has {z.files}")
        return np.asarray(z["frames"]), np.asarray(z["xy"], np.float64)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from trumans.scenes.io import load_scene
    from trumans.track.model_io import load_contact_models
    from trumans.sequence import load_sequence, save_sequence

    from trumans.track.interactions import TrackerConfig, track
    from trumans.out_paths import check_out, refuse_dataset_file

    check_out(args.out, "file")
    refuse_dataset_file(args.out)
    seq = load_sequence(args.input)
    scene = load_scene(_scene_folder(args.scene, seq.scene, Path(args.input)))
    model = load_contact_models(args.contact_checkpoint)
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
