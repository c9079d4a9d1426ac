"""Export a trained filter run as the shipped refine checkpoint (models/refine.pt).

    python scripts/ship_refine.py runs/filter/checkpoint.pt --out models/refine.pt \
        --command "trumans train --task filter --data data/synth_v5 --out runs/filter --steps 3000"

Keeps the EMA weights only, in float16 (``trumans.train.tasks.filter.export_checkpoint``; the fitted joint
skip in ``extra['wiener']`` stays float32), no optimiser state, and records the training command (by
default the source's own, so a shipped file can be re-exported in place).

Then fits the residual step's basis (``trumans.refine.residual_basis``, ``extra['residual_basis']``): the
exported network, every post-step off, refines ``--basis-clips`` corpus **train** clips under the
training corruption (``trumans.refine.corrupt`` at its defaults), and the basis is the leading
``--basis-rank`` patterns of its errors low-passed by ``--basis-sigma`` frames (the Gaussian the residual
step then uses inside the subspace). ``--basis-rank 0`` ships no basis. Chosen on the held-out families
(docs/results.md): rank 24 of 72, sigma 2 frames.
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from trumans.model.checkpoint import load_checkpoint, save_checkpoint, shipped_data_record
from trumans.refine.benchmark import corrupt_family, real_body_clips
from trumans.refine.frame import JOINTS, pack_frames
from trumans.refine.pipeline import HOIFilter, RefineOptions
from trumans.refine.post_steps import STEPS, PostStepsConfig
from trumans.refine.residual_basis import BASIS_KEY, fit_residual_basis
from trumans.skeleton import NUM_JOINTS
from trumans.train.tasks.filter import export_checkpoint


def network_outputs(filt: HOIFilter, tracked: list[np.ndarray], fps: list[float]) -> list[np.ndarray]:
    """The network's blended joints (T, 24, 3) m for tracked joints (T, 24, 3) m (NaN = missing), every
    post-step off."""
    frames = []
    for t in tracked:
        f = pack_frames(np.nan_to_num(t), None, np.broadcast_to(np.eye(4), (len(t), 4, 4)))
        f[:, JOINTS] = t.reshape(len(t), -1)  # missing joints stay missing
        frames.append(f)
    off = replace(RefineOptions(), post=PostStepsConfig().switched(**{s.name: False for s in STEPS}))
    outs = filt.refine_many(frames, fps, [filt.categories[0]] * len(frames), off)
    return [o[:, JOINTS].reshape(-1, NUM_JOINTS, 3).astype(np.float64) for o in outs]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint")
    p.add_argument("--out", default="models/refine.pt")
    p.add_argument("--command", default=None, help="the training command, recorded in meta (default: the source's)")
    p.add_argument("--basis-rank", type=int, default=24, help="rank of the residual basis (0: none)")
    p.add_argument("--basis-clips", type=int, default=30, help="corpus train clips the basis is fitted on")
    p.add_argument("--basis-seed", type=int, default=0, help="which clips, and the corruption's draws")
    p.add_argument("--basis-sigma", type=float, default=2.0,
                   help="the residual's Gaussian inside the subspace (frames at the filter's rate); the errors are "
                        "low-passed by it for the fit")
    a = p.parse_args(argv)
    src = load_checkpoint(a.checkpoint, kind="filter")
    ck = export_checkpoint(src)
    command = a.command if a.command is not None else str(src.meta.get("train_command", ""))
    extra, meta = {k: v for k, v in ck.extra.items() if k != BASIS_KEY}, {**ck.meta, "train_command": command}
    meta.pop(BASIS_KEY, None)
    if a.basis_rank > 0:
        filt = HOIFilter(replace(ck, extra=extra))
        clips = real_body_clips("train", a.basis_clips, a.basis_seed)
        tracked = corrupt_family("default", clips, a.basis_seed)
        outs = network_outputs(filt, tracked, [c.fps for c in clips])
        sigma = a.basis_sigma
        basis = fit_residual_basis(outs, [c.joints for c in clips], a.basis_rank, sigma)
        extra[BASIS_KEY] = basis.to_extra()
        meta[BASIS_KEY] = {"rank": a.basis_rank, "clips": len(clips), "seed": a.basis_seed, "sigma_frames": sigma,
                           "corruption": "the training corruption (trumans.refine.corrupt defaults, no IMU)",
                           "frames": int(sum(len(c.joints) for c in clips))}
    out = replace(ck, extra=extra, meta=meta, data=shipped_data_record(ck.data))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    save_checkpoint(a.out, out)
    n = sum(v.numel() for v in out.model_state.values())
    print(json.dumps({"out": a.out, "bytes": Path(a.out).stat().st_size, "parameters": n, "data": ck.data,
                      "wiener": "wiener" in ck.extra, BASIS_KEY: meta.get(BASIS_KEY)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
