"""The HOI filter's post-steps: one ordered pipeline, one config.

After the network's windows are blended (``HOIFilter.refine_many``), the refined clip at the
filter's rate goes through ``STEPS`` in this order (``run_post_steps``):

1. ``residual`` - the tracked input's low frequencies come back: the output is the filter's plus
   the low-passed difference to the input, planted feet held (``residual.py``). First: the
   network's slow error goes before the steps that read the body (stances, rests) do.
2. ``body_drift`` - the whole-body drift's changes seen by the planted feet are removed
   (``body_drift.py``), only where the fitted drift is over ``min_rms_m`` (5 cm rms): on real
   motion it reads 4-14 mm from clean feet that roll and pivot, and a smaller fit costs more than it
   corrects (docs/refine.md). It moves every joint, and the steps after it read the corrected body.
3. ``foot_lock`` - each planted foot joint is held on its stance (all but one point for a short
   one, its slow path for a long one), the legs following by IK (``foot_lock.py``). After the drift fit, which reads the same stances: the lock pins the
   feet where the drift-corrected body stands.
4. ``rest_pooling`` - one object pose per rest, pooled over the whole rest; with ``hand_link``,
   moves held rigidly by a wrist follow it and tie the rests on either side (``object_rest.py``).
   After the body drift: the moves follow the corrected wrists.
5. ``hinge`` - the object turns about one hinge fitted to the whole sequence, for the hinged
   categories (``object_hinge.py``; ``HingeConfig.categories``, or every object with
   ``any_category``). Only after rest pooling (``needs``): it reduces the pooled rotations to one
   degree of freedom.
6. ``gate`` - do no harm: the body's joints are blended with the tracked input by how noisy the
   input is there, joint by joint (``gate.py``: clean input comes back as it came; missing, frozen
   and spiking entries are the filter's). After the steps that change the body: it judges their
   result against the input.
7. ``smoother`` - where the filter disagrees with a Gaussian smoother of the input by more than the
   input's noise explains, the smoother takes an inverse-variance share, joint by joint, feet left to
   the lock (``smoother_blend.py``). After the gate: on clean input the gate hands the input back
   and the share stays ~0.
8. ``bones`` - every bone gets the input's own length, measured robustly over the tracked frames
   (``bones.py``): any skeleton's proportions come back as they went in. After the gate and the
   smoother: the blend of two bodies does not keep lengths.
9. ``floor`` - the body's height from its planted feet on z = 0, and no foot joint under the floor
   (``floor.py``). Last: it moves the body as one piece, so the lengths stay.

Every step has one signature, ``apply(clip: RefinedClip, config) -> frames (T, 235)``, and its own
frozen config with an ``enabled`` switch; ``PostStepsConfig`` nests them under the step names, so
every parameter of every step is set in one place (``RefineOptions.post``), and ``trumans refine`` /
``trumans eval refine`` generate their ``--no-<flag>`` switches from ``STEPS``
(``trumans.refine.post_args``). The names a clip's run reports (``PostStepsConfig.steps_for``, what
``trumans refine --json`` prints as ``post_steps``) are the steps that run, each followed by its
sub-switches that are on (``rest_pooling``, ``hand_link``). No step imports another but for the
stance detection and the stance corrections (``body_drift.stance_mask``, ``foot_lock.stance_corrections``).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Callable

import numpy as np

from trumans.config_data import config_from_dict
from trumans.refine.body_drift import DriftConfig, remove_body_drift
from trumans.refine.bones import BonesConfig, input_bone_lengths, project_bone_lengths
from trumans.refine.floor import FloorConfig, floor_offset, keep_above_floor
from trumans.refine.foot_lock import LockConfig, lock_feet
from trumans.refine.frame import FRAME_DIM, JOINTS
from trumans.refine.gate import GateConfig, gate_joints, noise_level
from trumans.refine.object_hinge import HingeConfig, fit_hinge
from trumans.refine.object_rest import RestConfig, pool_rest
from trumans.refine.residual import ResidualConfig, keep_low_frequencies
from trumans.refine.residual_basis import ResidualBasis
from trumans.refine.smoother_blend import BlendConfig, blend_with_smoother
from trumans.refine.tracked import TrackedBody
from trumans.skeleton import NUM_JOINTS

__all__ = ["RefinedClip", "SubSwitch", "PostStep", "STEPS", "PostStepsConfig", "run_post_steps"]


@dataclass(frozen=True)
class RefinedClip:
    """One refined clip as the post-steps see it, at the filter's rate.

    frames: (T, 235) world frame vectors, the blended filter output (then each step's output);
    tracked: (T, 235) the tracked input resampled to the same frames (NaN = missing); fps: the
    filter's frames per second; category: the object's category; tracked_body: the tracked joints
    as the input guards read them (gaps filled, cubic-fit residual; ``tracked.TrackedBody``), read
    once per clip: default read from ``tracked``, and ``dataclasses.replace`` hands it on;
    residual_basis: the filter checkpoint's subspace for the input residual (``residual_basis.py``;
    None: the residual step's plain Gaussian)."""

    frames: np.ndarray
    tracked: np.ndarray
    fps: float
    category: str
    tracked_body: TrackedBody | None = None
    residual_basis: ResidualBasis | None = None

    def __post_init__(self) -> None:
        F, R = np.shape(self.frames), np.shape(self.tracked)
        if len(F) != 2 or F[1] != FRAME_DIM or R != F:
            raise ValueError(f"frames and tracked must both be (T, {FRAME_DIM}), got {F} and {R}")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps must be a positive number, got {self.fps}")
        if self.tracked_body is None:
            object.__setattr__(self, "tracked_body", TrackedBody.read(_body(self.tracked)))
        elif self.tracked_body.joints.shape != (F[0], NUM_JOINTS, 3):
            raise ValueError(f"tracked_body has {self.tracked_body.joints.shape[0]} frames, the clip {F[0]}")


@dataclass(frozen=True)
class SubSwitch:
    """A boolean field of a step's config with its own ``--no-<flag>`` switch (``does``: one line for
    the help); reported after its step's name when on."""

    field: str
    flag: str
    does: str


def _always(config: Any, category: str) -> bool:
    return True


@dataclass(frozen=True)
class PostStep:
    """A post-step: name (its ``PostStepsConfig`` field and its reported name), flag (``--no-<flag>``),
    its config class, ``apply(clip, config) -> frames (T, 235)``, what it does (one line, for the
    help); optionally ``applies(config, category)`` (the categories it runs for), ``needs`` (a step
    that must run for this one to), ``subs`` (sub-switches) and ``force`` (a boolean config field
    that ``--<flag>`` sets, ``force_help`` its help)."""

    name: str
    flag: str
    config: type
    apply: Callable[[RefinedClip, Any], np.ndarray]
    does: str
    applies: Callable[[Any, str], bool] = _always
    needs: str | None = None
    subs: tuple[SubSwitch, ...] = ()
    force: str | None = None
    force_help: str = ""


def _residual(clip: RefinedClip, config: ResidualConfig) -> np.ndarray:
    return _with_body(clip.frames, keep_low_frequencies(_body(clip.frames), clip.tracked_body, clip.fps, config,
                                                        clip.residual_basis))


def _body_drift(clip: RefinedClip, config: DriftConfig) -> np.ndarray:
    return remove_body_drift(clip.frames, clip.fps, config)


def _foot_lock(clip: RefinedClip, config: LockConfig) -> np.ndarray:
    return lock_feet(clip.frames, clip.fps, config)


def _rest_pooling(clip: RefinedClip, config: RestConfig) -> np.ndarray:
    return pool_rest(clip.frames, clip.tracked, clip.fps, config)


def _hinge(clip: RefinedClip, config: HingeConfig) -> np.ndarray:
    return fit_hinge(clip.frames, clip.tracked, config)


def _body(frames: np.ndarray) -> np.ndarray:
    return np.asarray(frames, np.float64)[:, JOINTS].reshape(len(frames), -1, 3)


def _with_body(frames: np.ndarray, joints: np.ndarray) -> np.ndarray:
    out = np.array(frames, dtype=np.float32, copy=True)
    out[:, JOINTS] = joints.reshape(len(out), -1)
    return out


def _gate(clip: RefinedClip, config: GateConfig) -> np.ndarray:
    return _with_body(clip.frames, gate_joints(_body(clip.frames), clip.tracked_body, clip.fps, config))


def _smoother(clip: RefinedClip, config: BlendConfig) -> np.ndarray:
    return _with_body(clip.frames, blend_with_smoother(_body(clip.frames), clip.tracked_body, clip.fps, config))


def _bones(clip: RefinedClip, config: BonesConfig) -> np.ndarray:
    body = clip.tracked_body
    lengths = input_bone_lengths(body.joints, noise_level(body), config)
    return _with_body(clip.frames, project_bone_lengths(_body(clip.frames), lengths))


def _floor(clip: RefinedClip, config: FloorConfig) -> np.ndarray:
    offset = floor_offset(clip.tracked_body, config)
    return _with_body(clip.frames, keep_above_floor(_body(clip.frames), clip.fps, offset, config))


STEPS: tuple[PostStep, ...] = (
    PostStep("residual", "residual", ResidualConfig, _residual,
             "keep the tracked input's low frequencies: add the low-passed difference between input and filter "
             "(trumans.refine.residual)"),
    PostStep("body_drift", "drift-correction", DriftConfig, _body_drift,
             "remove the whole-body drift's changes seen by the planted feet, where they are larger than real "
             "feet's own roll and pivot (trumans.refine.body_drift)"),
    PostStep("foot_lock", "foot-lock", LockConfig, _foot_lock,
             "hold each planted foot joint at one point per stance, the legs following by IK "
             "(trumans.refine.foot_lock)"),
    PostStep("rest_pooling", "rest-pooling", RestConfig, _rest_pooling,
             "pool one object pose over each rest of the object (the filter's pose stays in every frame; "
             "trumans.refine.object_rest)",
             subs=(SubSwitch("hand_link", "hand-link",
                             "let a move held rigidly by a wrist follow the wrist and tie the rests on either side "
                             "(each rest is pooled on its own; trumans.refine.object_rest)"),)),
    PostStep("hinge", "hinge", HingeConfig, _hinge,
             "fit a hinge, whatever the category (trumans.refine.object_hinge)",
             applies=HingeConfig.applies_to, needs="rest_pooling", force="any_category",
             force_help="the object turns about one fixed hinge: fit it to the whole sequence after rest pooling "
                        "(default: for the hinged categories, door; trumans.refine.object_hinge)"),
    PostStep("gate", "gate", GateConfig, _gate,
             "blend the body with the tracked input by the input's local jitter: clean input comes back as it came "
             "(trumans.refine.gate)"),
    PostStep("smoother", "smoother-blend", BlendConfig, _smoother,
             "blend in a Gaussian smoother of the input where the filter disagrees with it by more than the input's "
             "noise explains, by inverse-variance weights (trumans.refine.smoother_blend)"),
    PostStep("bones", "input-bones", BonesConfig, _bones,
             "give every bone the input's own length, measured over the tracked frames (trumans.refine.bones)"),
    PostStep("floor", "floor", FloorConfig, _floor,
             "put the planted feet on the floor z = 0 and no foot joint under it (trumans.refine.floor)"),
)


@dataclass(frozen=True)
class PostStepsConfig:
    """One config per post-step (``STEPS``, in their order), each with ``enabled``."""

    residual: ResidualConfig = field(default_factory=ResidualConfig)
    body_drift: DriftConfig = field(default_factory=DriftConfig)
    foot_lock: LockConfig = field(default_factory=LockConfig)
    rest_pooling: RestConfig = field(default_factory=RestConfig)
    hinge: HingeConfig = field(default_factory=HingeConfig)
    gate: GateConfig = field(default_factory=GateConfig)
    smoother: BlendConfig = field(default_factory=BlendConfig)
    bones: BonesConfig = field(default_factory=BonesConfig)
    floor: FloorConfig = field(default_factory=FloorConfig)

    def switched(self, **enabled: bool) -> PostStepsConfig:
        """A copy with the named steps switched on / off, e.g. ``switched(foot_lock=False, hinge=False)``."""
        names = [s.name for s in STEPS]
        unknown = sorted(set(enabled) - set(names))
        if unknown:
            raise ValueError(f"unknown post-steps {unknown}; the steps: {names}")
        return replace(self, **{k: replace(getattr(self, k), enabled=bool(v)) for k, v in enabled.items()})

    def runs(self, category: str) -> list[str]:
        """The names of the steps that run for an object of ``category``, in order."""
        out: list[str] = []
        for step in STEPS:
            cfg = getattr(self, step.name)
            if cfg.enabled and step.applies(cfg, category) and (step.needs is None or step.needs in out):
                out.append(step.name)
        return out

    def steps_for(self, category: str) -> list[str]:
        """What a run for ``category`` reports: the steps that run, each followed by its sub-switches
        that are on (e.g. ``['body_drift', 'foot_lock', 'rest_pooling', 'hand_link', 'hinge']``)."""
        by_name = {s.name: s for s in STEPS}
        return [n for name in self.runs(category)
                for n in [name] + [s.field for s in by_name[name].subs if getattr(getattr(self, name), s.field)]]

    def to_dict(self) -> dict:
        """Plain data (``from_dict`` reads it back)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, where: str = "post") -> PostStepsConfig:
        """From plain data; keys left out keep the defaults, unknown keys are errors naming the key
        (``trumans.config_data.config_from_dict``)."""
        return config_from_dict(cls, d, where)


def run_post_steps(clip: RefinedClip, config: PostStepsConfig) -> np.ndarray:
    """``clip.frames`` through the steps that run for ``clip.category`` (``PostStepsConfig.runs``),
    in order -> (T, 235) world frame vectors at ``clip.fps``."""
    frames = clip.frames
    for name in config.runs(clip.category):
        step = next(s for s in STEPS if s.name == name)
        frames = step.apply(replace(clip, frames=frames), getattr(config, name))
    return frames


assert [s.name for s in STEPS] == [f.name for f in fields(PostStepsConfig)], "STEPS and PostStepsConfig disagree"
assert all(s.config is type(getattr(PostStepsConfig(), s.name)) for s in STEPS), "a step's config class is not its field's"
