"""Refining tracked human-object sequences with the HOI filter (I'm-HOI §3.2) at any length.

The tracked sequence (NaN = missing) is resampled to the filter's fps, cut into windows of ``L``
frames overlapping by ``overlap`` (``trumans.refine.windows``; a short one is padded with missing
frames), each window is put in its own canonical frame computed from the tracked input, denoised
as a batch, turned back to the world, blended across the overlaps, and resampled back to the
input's frames. Sampling starts from noise conditioned on the tracked input (the paper) or,
with ``mode="sdedit"``, from the tracked input noised to ``strength`` (Meng et al. 2022). Between
the blend and the resampling back, the clip goes through the post-steps at the filter's rate
(``trumans.refine.post_steps``: body drift, foot lock, object rests, hinge; ``RefineOptions.post``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import torch

from trumans.refine.filter import FilterModel, filter_window, category_indices, configure_skip, prepare_windows, sample_x0
from trumans.refine.frame import (FRAME_DIM, IMU_A, IMU_FLAG, IMU_R, JOINTS, OBJ_R, OBJ_T, fill_missing, frames_from_sequence, from_frame,
                               orthonormalize_6d, resample_frames, sequence_from_frames)
from trumans.refine.leg_swap import unswap_leg_frames
from trumans.refine.outliers import drop_frozen_frames, drop_frozen_joints, drop_object_flips, unflip_object
from trumans.refine.post_steps import PostStepsConfig, RefinedClip, run_post_steps
from trumans.refine.residual_basis import BASIS_KEY, ResidualBasis
from trumans.refine.tracked import TrackedBody
from trumans.refine.windows import blend_windows, window_starts
from trumans.model.checkpoint import Checkpoint, load_checkpoint
from trumans.sequence import Sequence
from trumans.paths import MODELS_DIR

__all__ = ["RefineOptions", "HOIFilter", "DEFAULT_CHECKPOINT"]

DEFAULT_CHECKPOINT = MODELS_DIR / "refine.pt"
Mode = Literal["noise", "sdedit"]


@dataclass(frozen=True)
class RefineOptions:
    """num_steps: DDIM steps; mode: 'noise' (the paper) or 'sdedit'; strength: SDEdit's noise level
    in (0, 1]; eta: DDIM stochasticity (0 = deterministic given the seed); batch: windows per
    network call; seed: the sampling noise; drop_failures: treat repeated (frozen) frames as
    missing, turn object rotations flipped by π about an own axis back (read from the whole sequence) and
    treat other rotations that flip and back within a second as missing, before filtering
    (``trumans.refine.outliers``); held_joints: a joint held bit for bit for two repeats or more is
    missing (``outliers.frozen_joint_mask``); leg_swaps: legs read as swapped from the whole sequence
    are exchanged back (``trumans.refine.leg_swap``); post: the post-steps after filtering, each with its switch and
    parameters (``trumans.refine.post_steps``: body drift, foot lock, rest pooling with the hand
    link, hinge for the hinged categories)."""

    num_steps: int = 2
    mode: Mode = "noise"
    strength: float = 0.5
    eta: float = 0.0
    batch: int = 256
    seed: int = 0
    drop_failures: bool = True
    held_joints: bool = True
    leg_swaps: bool = True
    post: PostStepsConfig = field(default_factory=PostStepsConfig)

    def post_steps(self, category: str) -> list[str]:
        """The steps after the network these options run for an object of ``category``, in order,
        with the sub-switches that are on (``PostStepsConfig.steps_for``; ``trumans refine`` reports it)."""
        return self.post.steps_for(category)

    def __post_init__(self) -> None:
        if self.mode not in ("noise", "sdedit"):
            raise ValueError(f"mode must be 'noise' or 'sdedit', got {self.mode!r}")
        if self.num_steps < 1 or self.batch < 1:
            raise ValueError(f"num_steps and batch must be >= 1, got {self.num_steps}, {self.batch}")
        if not 0 < self.strength <= 1:
            raise ValueError(f"strength must be in (0, 1], got {self.strength}")


class HOIFilter:
    """A loaded filter checkpoint: ``refine_frames`` on frame vectors, ``refine_sequence`` on a Sequence."""

    def __init__(self, ckpt: Checkpoint, device: str | torch.device = "cpu") -> None:
        self.ckpt = ckpt
        self.device = torch.device(device)
        self.model: FilterModel = configure_skip(ckpt.build_model(), ckpt).to(self.device)
        self.diffusion = ckpt.build_diffusion().to(self.device)
        self.normalizer = ckpt.normalizer
        self.categories: list[str] = [str(c) for c in ckpt.extra["categories"]]
        (self.window, self.overlap), self.fps = filter_window(ckpt), float(ckpt.fps)
        basis = ckpt.extra.get(BASIS_KEY)
        self.residual_basis = None if basis is None else ResidualBasis.from_extra(basis)

    @classmethod
    def load(cls, path: str | Path | None = None, device: str | torch.device = "cpu") -> "HOIFilter":
        """Load ``path`` (default: the shipped ``models/refine.pt``); the network runs on ``device`` (the
        windows' preparation, blending and post-steps are numpy on the CPU)."""
        return cls(load_checkpoint(DEFAULT_CHECKPOINT if path is None else path, kind="filter"), device=device)

    def refine_frames(self, frames: np.ndarray, fps: float, category: str,
                      options: RefineOptions = RefineOptions()) -> np.ndarray:
        """Tracked world frame vectors (T, 235) at ``fps`` (NaN = missing) -> refined (T, 235)."""
        return self.refine_many([frames], [fps], [category], options)[0]

    def refine_many(self, frames: list[np.ndarray], fps: list[float], categories: list[str],
                    options: RefineOptions = RefineOptions()) -> list[np.ndarray]:
        """Several tracked sequences at once: every window of every sequence goes through the network
        in batches of ``options.batch`` (one forward per DDIM step and batch, not per window). Each
        sequence's starting noise is drawn from its own generator seeded with ``options.seed``, so
        with ``eta = 0`` a sequence's result does not depend on its batch mates.
        frames[i]: (T_i, 235) world frame vectors at fps[i] (NaN = missing) -> [(T_i, 235)]."""
        if not len(frames) == len(fps) == len(categories):
            raise ValueError(f"need one fps and category per sequence, got {len(frames)} / {len(fps)} / {len(categories)}")
        if not frames:
            return []
        cats = category_indices(list(categories), self.categories)
        parts = [self._windows(f, r, options) for f, r in zip(frames, fps)]
        L = self.window
        cond = torch.cat([p["inp"].cond for p in parts])
        category = torch.from_numpy(np.concatenate([np.full(len(p["starts"]), c) for p, c in zip(parts, cats)]))
        noise = torch.cat([torch.randn((len(p["starts"]), L, FRAME_DIM), generator=torch.Generator().manual_seed(int(options.seed)))
                           for p in parts])
        gen = torch.Generator().manual_seed(int(options.seed))  # CPU noise: the same draws on every device
        x0 = torch.empty_like(noise)
        dev = self.device
        for s in range(0, len(cond), options.batch):
            sl = slice(s, s + options.batch)
            start = cond[sl, :, :FRAME_DIM].clone() if options.mode == "sdedit" else None  # tracked, gaps interpolated
            x0[sl] = sample_x0(self.model, self.diffusion, cond[sl].to(dev), category[sl].to(dev),
                               num_steps=options.num_steps, eta=options.eta, generator=gen, start=start,
                               noise=noise[sl], strength=options.strength if options.mode == "sdedit" else 1.0).cpu()
        out = self.normalizer.denormalize(x0.numpy())
        results, i = [], 0
        for p, r, c in zip(parts, fps, categories):
            n = len(p["starts"])
            world = from_frame(out[i:i + n], p["inp"].origin, p["inp"].yaw)
            i += n
            blended = orthonormalize_6d(blend_windows(world, p["starts"], p["Tm"]))
            blended[:, IMU_FLAG] = np.round(np.clip(blended[:, IMU_FLAG], 0, 1))
            body = TrackedBody.read(p["tracked"][:, JOINTS].reshape(p["Tm"], -1, 3), filled=p["filled_joints"])
            blended = run_post_steps(RefinedClip(blended, p["tracked"], self.fps, c, tracked_body=body,
                                                         residual_basis=self.residual_basis), options.post)
            results.append(resample_frames(blended, self.fps, r, num_out=p["T"]))
        return results

    def _windows(self, frames: np.ndarray, fps: float, options: RefineOptions) -> dict:
        """One sequence's windows at the filter's rate: starts, model-rate length Tm, input length T,
        the network inputs (``prepare_windows``), the tracked frames at that rate (``tracked``) and
        their joints with the gaps filled (``filled_joints`` (Tm, 24, 3), for the post-steps);
        the failures the options name are read first (frozen frames and held joints -> missing, legs
        swapped back, flipped object rotations turned back or missing)."""
        f = np.asarray(frames, dtype=np.float32)
        if f.ndim != 2 or f.shape[1] != FRAME_DIM:
            raise ValueError(f"frame vectors must be (T, {FRAME_DIM}), got {f.shape}")
        T = f.shape[0]
        if T < 2:
            raise ValueError(f"a tracked sequence needs at least 2 frames, got {T}")
        if not np.isfinite(fps) or fps <= 0:
            raise ValueError(f"fps must be a positive number, got {fps}")
        if not np.isfinite(f[:, JOINTS].reshape(T, -1, 3)).all(-1).any():  # nothing to refine from
            raise ValueError("the tracked body is missing (NaN) on every frame; the filter fills gaps from what was "
                             "tracked around them - give a sequence with observed frames")
        if not np.isfinite(f[:, OBJ_T]).all(-1).any() or not np.isfinite(f[:, OBJ_R]).all(-1).any():
            raise ValueError("the tracked object's pose is missing (NaN) on every frame; give at least one observed "
                             "pose (or refine without that object)")
        # at the input's rate: resampling would blur exact repeats and blend flipped with unflipped
        if options.drop_failures:
            f = unflip_object(drop_frozen_frames(f))
        if options.held_joints:
            f = drop_frozen_joints(f)
        if options.leg_swaps:
            f = unswap_leg_frames(f)
        # model frames from time 0 over the whole duration (the last may end just past it)
        g = resample_frames(f, fps, self.fps, num_out=int(np.ceil((T - 1) / fps * self.fps - 1e-9)) + 1)
        if options.drop_failures:
            g = drop_object_flips(g, self.fps)  # what the whole-sequence reading left: short runs outvoted by their neighbours
        Tm, L = g.shape[0], self.window
        starts = window_starts(Tm, L, self.overlap)
        padded = np.concatenate([g, np.full((max(0, L - Tm), FRAME_DIM), np.nan, np.float32)])
        padded[Tm:, IMU_R] = padded[Tm:, IMU_A] = padded[Tm:, IMU_FLAG] = 0.0  # padding: no IMU either
        idx = starts[:, None] + np.arange(L)[None]
        filled = fill_missing(padded)  # once: the windows' condition and the post-steps' tracked body
        inp = prepare_windows(padded[idx], self.normalizer, filled_world=filled[idx])
        return {"starts": starts, "Tm": Tm, "T": T, "inp": inp, "tracked": g,
                "filled_joints": filled[:Tm, JOINTS].reshape(Tm, -1, 3)}

    def refine_sequence(self, seq: Sequence, category: str | None = None, object_name: str | None = None,
                        options: RefineOptions = RefineOptions()) -> tuple[Sequence, str]:
        """Refine ``seq`` (joints, optional rotations, one object's pose and optional IMU; NaN =
        missing) -> (refined Sequence with the same frames and fps, the object's name). The object's
        category is ``category`` or its own; other fields and objects are passed through."""
        frames, name = frames_from_sequence(seq, object_name)
        cat = category or seq.objects[name].category
        if not cat:
            raise ValueError(f"object {name!r} has no category; pass --category (one of {self.categories})")
        refined = self.refine_frames(frames, seq.fps, cat, options)
        out = sequence_from_frames(refined, seq.fps, name, cat, template=seq, imu=False)
        out.objects[name].imu_rot, out.objects[name].imu_acc = seq.objects[name].imu_rot, seq.objects[name].imu_acc
        out.allow_missing = False
        out.validate()
        return out, name
