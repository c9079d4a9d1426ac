"""The post-network corrections of the generator: one ordered pipeline, one config.

After each episode the network's joints go through ``STEPS`` in this order (``run_cleanup``):

1. ``attach_pelvis`` - the pinned pelvis goes back on the generated body. First: it repairs the
   network's own output, and the next steps measure that body (``attach_pelvis.py``).
2. ``seam`` - the jump at the seam with the context is blended out over a few new frames. Before
   the projection, so the blended frames get the body's bones too (``seam.py``).
3. ``bone_projection`` - the joints go onto the body's bone lengths; every later step keeps
   lengths exact (``bones.py``).
4. ``support_lift`` - where the feet carry the body, it rises until its lowest foot is on the floor.
   Right after the projection, which keeps the pelvis and lengthens short legs downward: without
   the lift the foot cleanup (hip fixed) would bend the knees (``support_lift.py``).
5. ``scene_pushout`` - a smooth root offset moves the new frames' body out of the scene. Before the
   arms and the feet: it moves the whole body, and they re-solve after it (``scene_pushout.py``).
6. ``containment`` - the hard constraint: an upright pelvis keeps the torso's clearance from
   anything and stays inside the room, whatever the network and the soft push-out left. Right
   after the push-out (which trades depth against change and may leave some) and before the arms
   and the feet, which re-solve on the moved body (``containment.py``).
7. ``seat_settle`` - the hard constraint on sitting: every seated frame's pelvis within 2 cm of its
   seat's height, the move faded into the frames around (``seat_settle.py``). After the push-outs,
   before the arms and the feet, whose IK re-solves on the moved body (the feet re-planted).
8. ``arm_pushout`` - a hand still in the scene is moved out by arm IK, except on frames where the
   plan reaches (the reach cleanup's). After the body push-out: only what the trunk could not take
   out (``arm_pushout.py``).
9. ``foot`` - planted feet locked on the floor, swings on smooth paths, the legs re-solved. After
   the push-outs: the feet re-lock where the moved body stands (``foot.py``).
10. ``reach`` - the acting arm onto the plan's hand target. Nothing after it but the guard moves
   the arm off its target (``reach.py``).
11. ``swept_guard`` - no joint passes through a solid between two frames: a frame that would is
   blended back toward the frame before. Last, so that it holds whatever every step before did
   (``swept.py``).

Every step has one signature, ``apply(episode: EpisodeBodies, config) -> joints (B, L, 24, 3)``,
and its own frozen config with an ``enabled`` switch; ``CleanupConfig`` nests them under the step
names, so every parameter of every step is set in one place (``SamplerConfig.cleanup``), and
``trumans sample`` / ``trumans eval synthesis`` generate their ``--no-<flag>`` switches from
``STEPS``. Every step that reads the scene gets its ``enclosed`` field (``trumans.scenes.sdf``:
a closed room's outside is solid, so a body past a wall is deep in it, not free). The steps read what the plan asks of the body from ``EpisodeBodies``: the action labels
(support lift), the pinned goals (attach pelvis), the reach weights and targets (arm push-out,
reach). The reach weights are scheduled by the controller (``Controller.next``) because they
follow the plan's hand phases across episodes (a release fades out over the next episode); their
ramps are the reach step's config, which the rollout gives the controller. Helpers the steps share
live in ``cleanup/common.py``; no step imports another.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable

import numpy as np

from trumans.sample.cleanup.arm_pushout import ArmPushConfig, push_arms_out
from trumans.sample.cleanup.attach_pelvis import AttachPelvisConfig, attach_pinned_pelvis
from trumans.sample.cleanup.bones import BoneProjectionConfig, project_bones
from trumans.sample.cleanup.containment import ContainmentConfig, contain
from trumans.sample.cleanup.foot import FootCleanupConfig, clean_feet
from trumans.sample.cleanup.reach import ReachCleanupConfig, clean_reach
from trumans.sample.cleanup.scene_pushout import PushOutConfig, push_out
from trumans.sample.cleanup.seam import SeamConfig, blend_seam
from trumans.sample.cleanup.seat_settle import SeatSettleConfig, settle_on_seat
from trumans.sample.cleanup.support_lift import SupportLiftConfig, lift_onto_feet, support_weights
from trumans.sample.cleanup.swept import SweptGuardConfig, guard_crossings
from trumans.scenes.sdf import SceneSDF

__all__ = ["EpisodeBodies", "CleanupStep", "STEPS", "CleanupConfig", "run_cleanup"]


@dataclass(frozen=True)
class EpisodeBodies:
    """One episode of B samples as the cleanup steps see it.

    joints: (B, L, 24, 3) world m, z up: the episode so far (its first k frames stand for the
    context; the steps keep them); context: (B, k >= 2, 24, 3) world m, the context frames as
    committed (the seam blend and the foot locks start from them); lengths: (24,) m, the body's
    bone lengths (root 0); labels: (B, L, N_A) action labels (0 off, 1 + progress on) over
    ``vocabulary``; fps: frames per second; pinned: (B,) bool, samples whose pelvis x, y the goal
    pinned at the last frame; reach_weight: (B, L, 2) in [0, 1] and reach_target: (B, L, 2, 3)
    world m, the (left, right) wrist's reach weight and target (``Controller.next``); sdf: the
    scene's signed distance field (floor excluded), or None without a scene (``run_cleanup`` gives
    the steps its ``enclosed`` form); seat_z: (B, L) the seated pelvis height of each frame of a
    sit phase, m, NaN elsewhere (``trumans.sample.guidance.seat.seated_heights``), or None."""

    joints: np.ndarray
    context: np.ndarray
    lengths: np.ndarray
    labels: np.ndarray
    vocabulary: tuple[str, ...]
    fps: float
    pinned: np.ndarray
    reach_weight: np.ndarray
    reach_target: np.ndarray
    sdf: SceneSDF | None = None
    seat_z: np.ndarray | None = None

    def __post_init__(self) -> None:
        J, C = np.shape(self.joints), np.shape(self.context)
        if len(J) != 4 or J[2:] != (24, 3) or len(C) != 4 or C[0] != J[0] or not 2 <= C[1] < J[1] or C[2:] != (24, 3):
            raise ValueError(f"need joints (B, L, 24, 3) and context (B, 2 <= k < L, 24, 3), got {J} and {C}")
        B, L = J[:2]
        for name, want in (("lengths", (24,)), ("labels", (B, L, len(self.vocabulary))), ("pinned", (B,)),
                           ("reach_weight", (B, L, 2)), ("reach_target", (B, L, 2, 3))) + \
                (() if self.seat_z is None else (("seat_z", (B, L)),)):
            if np.shape(getattr(self, name)) != want:
                raise ValueError(f"{name} must be {want} for joints {J}, got {np.shape(getattr(self, name))}")

    @property
    def k(self) -> int:
        """Context frames."""
        return int(np.shape(self.context)[1])


@dataclass(frozen=True)
class CleanupStep:
    """A cleanup step: name (its ``CleanupConfig`` field), flag (``--no-<flag>``), its config
    class, ``apply(episode, config) -> joints (B, L, 24, 3) world m``, what it does (one line, for
    the help), and optionally the config field that ``--<flag> VALUE`` sets (``option``, its help
    ``option_help``)."""

    name: str
    flag: str
    config: type
    apply: Callable[[EpisodeBodies, Any], np.ndarray]
    does: str
    option: str | None = None
    option_help: str = ""


def _attach_pelvis(ep: EpisodeBodies, config: AttachPelvisConfig) -> np.ndarray:
    return attach_pinned_pelvis(ep.joints, ep.pinned)


def _seam(ep: EpisodeBodies, config: SeamConfig) -> np.ndarray:
    if config.frames == 0:
        return ep.joints
    out = np.array(ep.joints, copy=True)
    out[:, ep.k:] = blend_seam(ep.context, ep.joints[:, ep.k:], config.frames)
    return out


def _bone_projection(ep: EpisodeBodies, config: BoneProjectionConfig) -> np.ndarray:
    return project_bones(ep.joints, ep.lengths, rigid_trunk=config.rigid_trunk)


def _support_lift(ep: EpisodeBodies, config: SupportLiftConfig) -> np.ndarray:
    return lift_onto_feet(ep.joints, support_weights(ep.labels, ep.vocabulary, config.seated_actions), ep.k)


def _scene_pushout(ep: EpisodeBodies, config: PushOutConfig) -> np.ndarray:
    return ep.joints if ep.sdf is None else push_out(ep.joints, ep.sdf, ep.k, config)


def _containment(ep: EpisodeBodies, config: ContainmentConfig) -> np.ndarray:
    if ep.sdf is None:
        return ep.joints
    weight = support_weights(ep.labels, ep.vocabulary)
    return contain(ep.joints, ep.sdf, weight, ep.k, config, fps=ep.fps)


def _seat_settle(ep: EpisodeBodies, config: SeatSettleConfig) -> np.ndarray:
    return ep.joints if ep.seat_z is None else settle_on_seat(ep.joints, ep.seat_z, ep.k, config)


def _arm_pushout(ep: EpisodeBodies, config: ArmPushConfig) -> np.ndarray:
    if ep.sdf is None:
        return ep.joints
    return push_arms_out(ep.joints, ep.lengths, ep.sdf, ep.k, keep=ep.reach_weight > 0, config=config)


def _foot(ep: EpisodeBodies, config: FootCleanupConfig) -> np.ndarray:
    # over the committed context (it seeds the locks) and the new frames
    return clean_feet(np.concatenate([ep.context, ep.joints[:, ep.k:]], 1), ep.lengths, ep.fps, ep.k, config,
                      sdf=ep.sdf if config.scene else None, seated=None if ep.seat_z is None else np.isfinite(ep.seat_z))


def _reach(ep: EpisodeBodies, config: ReachCleanupConfig) -> np.ndarray:
    if not (ep.reach_weight > 0).any():
        return ep.joints
    return clean_reach(ep.joints, ep.lengths, ep.reach_target, ep.reach_weight, ep.k, config)


def _swept_guard(ep: EpisodeBodies, config: SweptGuardConfig) -> np.ndarray:
    if ep.sdf is None:
        return ep.joints
    return guard_crossings(ep.joints, ep.sdf, ep.k, config, support_weights(ep.labels, ep.vocabulary))


STEPS: tuple[CleanupStep, ...] = (
    CleanupStep("attach_pelvis", "attach-pelvis", AttachPelvisConfig, _attach_pelvis,
                "put a pinned pelvis back on the generated body (cleanup/attach_pelvis.py)"),
    CleanupStep("seam", "seam-blend", SeamConfig, _seam,
                "blend the jump at episode seams out over --seam-blend frames (cleanup/seam.py)",
                option="frames", option_help="frames over which the jump at episode seams is blended out (0 = off)"),
    CleanupStep("bone_projection", "bone-projection", BoneProjectionConfig, _bone_projection,
                "put the joints on the body's bone lengths (cleanup/bones.py)"),
    CleanupStep("support_lift", "support-lift", SupportLiftConfig, _support_lift,
                "raise the body back onto its feet after the projection, where the feet carry it "
                "(cleanup/support_lift.py)"),
    CleanupStep("scene_pushout", "scene-pushout", PushOutConfig, _scene_pushout,
                "move the body out of the scene by a smooth root offset (cleanup/scene_pushout.py)"),
    CleanupStep("containment", "containment", ContainmentConfig, _containment,
                "keep an upright pelvis the torso's clearance from anything and inside the room: a hard "
                "projection (cleanup/containment.py)"),
    CleanupStep("seat_settle", "seat-settle", SeatSettleConfig, _seat_settle,
                "put a seated pelvis within a tolerance of its seat's height: a hard projection "
                "(cleanup/seat_settle.py)"),
    CleanupStep("arm_pushout", "arm-pushout", ArmPushConfig, _arm_pushout,
                "move a hand still in the scene out by arm IK (cleanup/arm_pushout.py)"),
    CleanupStep("foot", "foot-cleanup", FootCleanupConfig, _foot,
                "lock planted feet on the floor, smooth the swings, re-solve the legs (cleanup/foot.py)"),
    CleanupStep("reach", "reach-cleanup", ReachCleanupConfig, _reach,
                "move the acting arm onto the plan's hand targets (cleanup/reach.py)"),
    CleanupStep("swept_guard", "swept-guard", SweptGuardConfig, _swept_guard,
                "stop any joint passing through a solid between two frames (cleanup/swept.py)"),
)


@dataclass(frozen=True)
class CleanupConfig:
    """One config per cleanup step (``STEPS``, in their order), each with ``enabled``."""

    attach_pelvis: AttachPelvisConfig = field(default_factory=AttachPelvisConfig)
    seam: SeamConfig = field(default_factory=SeamConfig)
    bone_projection: BoneProjectionConfig = field(default_factory=BoneProjectionConfig)
    support_lift: SupportLiftConfig = field(default_factory=SupportLiftConfig)
    scene_pushout: PushOutConfig = field(default_factory=PushOutConfig)
    containment: ContainmentConfig = field(default_factory=ContainmentConfig)
    seat_settle: SeatSettleConfig = field(default_factory=SeatSettleConfig)
    arm_pushout: ArmPushConfig = field(default_factory=ArmPushConfig)
    foot: FootCleanupConfig = field(default_factory=FootCleanupConfig)
    reach: ReachCleanupConfig = field(default_factory=ReachCleanupConfig)
    swept_guard: SweptGuardConfig = field(default_factory=SweptGuardConfig)

    def switched(self, **enabled: bool) -> CleanupConfig:
        """A copy with the named steps switched on / off, e.g. ``switched(foot=False, reach=False)``."""
        names = [s.name for s in STEPS]
        unknown = sorted(set(enabled) - set(names))
        if unknown:
            raise ValueError(f"unknown cleanup steps {unknown}; the steps: {names}")
        return replace(self, **{k: replace(getattr(self, k), enabled=bool(v)) for k, v in enabled.items()})

    @property
    def uses_scene(self) -> bool:
        """Whether an enabled step reads the scene's field."""
        return (self.scene_pushout.enabled or self.containment.enabled or self.arm_pushout.enabled
                or self.swept_guard.enabled or (self.foot.enabled and self.foot.scene))


def run_cleanup(episode: EpisodeBodies, config: CleanupConfig,
                observe: Callable[[str, np.ndarray], None] | None = None) -> np.ndarray:
    """``episode.joints`` through the enabled ``STEPS`` in order -> (B, L, 24, 3) world m.
    ``observe(name, joints)``, when given, is called after every step (enabled or not) with the
    joints so far, e.g. to measure the network's bones before the projection; do not modify them."""
    joints = episode.joints
    if episode.sdf is not None:
        episode = replace(episode, sdf=episode.sdf.enclosed())
    for step in STEPS:
        cfg = getattr(config, step.name)
        if cfg.enabled:
            joints = step.apply(replace(episode, joints=joints), cfg)
        if observe is not None:
            observe(step.name, joints)
    return joints


assert [s.name for s in STEPS] == [f.name for f in fields(CleanupConfig)], "STEPS and CleanupConfig disagree"
assert all(s.config is type(getattr(CleanupConfig(), s.name)) for s in STEPS), "a step's config class is not its field's"
