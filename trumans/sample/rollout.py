"""Long motions: a plan rolled out episode by episode, as a batch or as a stream (TRUMANS §4.1, §5.4).

``sample_plan`` runs the closed-loop controller (``trumans.sample.controller``), the episode sampler
(``trumans.sample.sampler``) and the cleanup after it (``trumans.sample.cleanup.pipeline``) episode by
episode until the plan is done and returns every frame. With ``SamplerConfig.overlap`` = D > 0 (the
default, 5), every episode but the last commits only its first L - k - D new frames (the controller
is rewound to what they consumed, as ``stream`` does); the next episode starts from there and makes
the D frames the earlier one made and did not commit again: while it denoises, its x0 on those
frames is pulled onto the earlier frames with the crossfade's weights (``cleanup.seam.crossfade_weights``,
``EpisodeSampler.episode(lead=...)``: replacement inpainting, as in MDM's in-betweening), so what
it makes after them continues their motion, and its guidance keeps the earlier episode's goals
due on them (``_carried_goals``; without them the goal error rose 6.9 -> 10.5 cm). The cleanup then
puts them on the body's bones, out of the scene, feet down (its seam blend is off for these
episodes). No frame of the output comes from one network pass's edge alone, so the seam's jerk
(k = 2 context frames carry no acceleration) is spread over D frames (issue 35, docs/results.md).
``stream`` is the real-time
form: a Python generator that yields new frames as soon as they are made and accepts a new plan
at any time through ``send``; after a new plan it commits 2, then 4, then 8 new frames per
episode before going back to full episodes (the paper's incremental schedule, §5.4), so the body
reacts after one short episode instead of a full one.
"""
from __future__ import annotations

import time
from collections.abc import Generator
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from trumans.body import sit_offset
from trumans.model.checkpoint import Checkpoint
from trumans.skeleton import JOINT_INDEX, heading as body_heading

from trumans.sample.carry_plan import planned_object_poses
from trumans.sample.cleanup.bones import bone_lengths_of
from trumans.sample.cleanup.pipeline import EpisodeBodies, run_cleanup
from trumans.sample.cleanup.seam import crossfade_weights
from trumans.sample.controller import Controller, Phase, compile_plan
from trumans.sample.guidance.seat import seated_heights
from trumans.sample.plan import Plan
from trumans.sample.sampler import EpisodeSampler, Goal

__all__ = ["SampleResult", "start_pose", "body_pose", "start_context", "sample_plan", "stream", "INCREMENTAL_SCHEDULE"]

PELVIS = JOINT_INDEX["pelvis"]
INCREMENTAL_SCHEDULE: tuple[int, ...] = (2, 4, 8)


@dataclass
class SampleResult:
    """joints: (B, T, 24, 3) world m at ``fps``; labels: (B, T, N_A) action labels used; phase:
    (B, T) index into ``phases`` (-1 = before the first / after the last); episodes: count;
    seconds: wall-clock time spent sampling episodes (s)."""

    joints: np.ndarray
    labels: np.ndarray
    phase: np.ndarray
    phases: list[Phase]
    fps: float
    vocabulary: list[str]
    episodes: int
    seconds: float
    episode_starts: list[int] = field(default_factory=list)
    goals: list[tuple[int, int, str, np.ndarray]] = field(default_factory=list)  # (frame, sample, joint, point)
    raw_bone_cv: float = float("nan")  # bone-length std/mean of the network's output before projection
    sit_offset: float = 0.171  # pelvis height above a seat surface for this body, m (``sit_offset``)
    context_frames: int = 0  # k: episode i's first new frame (a seam) is episode_starts[i] + k

    @property
    def seconds_per_episode(self) -> float:
        return self.seconds / max(self.episodes, 1)

    @property
    def realtime_factor(self) -> float:
        """Seconds of motion made per second of sampling."""
        return (self.joints.shape[1] / self.fps) / max(self.seconds, 1e-9)


def start_pose(ckpt: Checkpoint) -> np.ndarray:
    """(24, 3) standing pose in the canonical frame (pelvis at x = y = 0, facing +x): the
    checkpoint's ``meta['start_pose']``, else the training data's mean pose."""
    if "start_pose" in ckpt.meta:
        p = np.asarray(ckpt.meta["start_pose"], dtype=np.float32)
        if p.shape != (24, 3) or not np.isfinite(p).all():
            raise ValueError(f"checkpoint meta start_pose must be finite (24, 3), got {p.shape}")
        return p
    mean = ckpt.normalizer.mean[: 24 * 3].reshape(24, 3).copy()
    mean[:, :2] -= mean[PELVIS, :2]
    return mean


def body_pose(frame: np.ndarray, what: str = "the body frame") -> np.ndarray:
    """A body to sample with from one standing frame (24, 3) world m, z up -> (24, 3) canonical
    (pelvis at x = y = 0, facing +x) with its lowest foot joint at its rest height; the sampler keeps
    its bone lengths. Raises ValueError naming ``what`` unless the frame is finite and stands: both
    legs at least 85 % straight (hip to ankle against thigh + shin) and the trunk within 30 degrees
    of vertical."""
    from trumans.model.motion_stats import canonical_pose
    from trumans.skeleton import NUM_JOINTS

    from trumans.sample.cleanup.support_lift import lowest_foot_height

    f = np.asarray(frame, dtype=np.float64)
    if f.shape != (NUM_JOINTS, 3) or not np.isfinite(f).all():
        raise ValueError(f"{what} must be finite joints (24, 3), got shape {f.shape}"
                         + ("" if f.shape != (NUM_JOINTS, 3) else " with NaN / inf"))
    L = bone_lengths_of(f)
    for side in ("left", "right"):
        hip, knee, ankle = (JOINT_INDEX[f"{side}_{n}"] for n in ("hip", "knee", "ankle"))
        if np.linalg.norm(f[ankle] - f[hip]) < 0.85 * (L[knee] + L[ankle]):
            raise ValueError(f"{what} does not stand (the {side} knee is bent); give a standing frame (PATH:FRAME)")
    trunk = f[JOINT_INDEX["neck"]] - f[PELVIS]
    if trunk[2] < np.cos(np.radians(30.0)) * np.linalg.norm(trunk):
        raise ValueError(f"{what} does not stand (the trunk leans more than 30 degrees); give a standing frame "
                         f"(PATH:FRAME)")
    p = canonical_pose(f[None])[0]
    p[:, 2] -= lowest_foot_height(p)
    return p.astype(np.float32)


def start_context(ckpt: Checkpoint, xy: np.ndarray, heading: float, batch: int = 1,
                  pose: np.ndarray | None = None) -> np.ndarray:
    """(B, k, 24, 3) world: the start pose (``pose`` (24, 3) canonical, default the checkpoint's
    ``start_pose``) standing still at floor point xy facing ``heading``."""
    p = (start_pose(ckpt) if pose is None else np.asarray(pose)).astype(np.float64)
    c, s = np.cos(heading), np.sin(heading)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    w = p @ R.T + np.array([xy[0], xy[1], 0.0])
    return np.broadcast_to(w.astype(np.float32), (batch, ckpt.k, 24, 3)).copy()


def _speed(ckpt: Checkpoint) -> float:
    return float(ckpt.meta.get("walk_speed", 1.0))


def action_seconds(ckpt: Checkpoint) -> dict[str, float]:
    """The shipped generator's typical action durations (s) by action name (meta["action_seconds"]), for plans."""
    return {str(k): float(v) for k, v in dict(ckpt.meta.get("action_seconds", {})).items()}


@dataclass
class _Episode:
    new: np.ndarray  # (B, L - k, 24, 3) world
    labels: np.ndarray  # (B, L, N_A)
    phase: np.ndarray  # (B, L)
    goals: list[Goal]
    raw_cv: float


def _step(sampler: EpisodeSampler, controllers: list[Controller], context: np.ndarray, prev_labels: np.ndarray,
          lengths: np.ndarray, generator: torch.Generator | None, seat_offset: float,
          pending: np.ndarray | None = None, carried: tuple[tuple[Goal, ...], ...] = ()) -> _Episode:
    """One episode for every sample: the controls, the network (with its guidance), then the
    cleanup pipeline (``trumans.sample.cleanup.pipeline``) on the body with bone ``lengths``;
    ``seat_offset``: the body's pelvis height above a seat surface (``sit_offset``), m; ``pending``
    (B, D, 24, 3): the previous episode's uncommitted frames, which the network's first D new frames
    follow with the crossfade's weights while it denoises (``EpisodeSampler.episode(lead=...)``; the
    cleanup then puts the blend on the bones, out of the scene, feet down); ``carried``: the previous
    episode's goals due in those frames, which this episode's guidance keeps (``_carried_goals``)."""
    config = sampler.config
    moved = planned_object_poses(controllers, sampler.grids)  # objects the plan has moved so far
    ctrls = [c.next(context[b, -1, PELVIS, :2], prev_labels[b]) for b, c in enumerate(controllers)]
    seated = [seated_heights(c.phases, ctl.phases, seat_offset, sampler.k, config.guidance.seat.seated_kinds)
              for c, ctl in zip(ctrls, controllers)]
    seat = seated if config.guidance.seat.enabled else [()] * len(seated)
    goals = [Goal(tuple(c.goal), guide=c.guide, heading=c.heading, pelvis_z=z) if c.hand_goal is None else
             Goal(tuple(c.hand_goal), c.hand, c.hand_frame, c.guide, pelvis_z=z) for c, z in zip(ctrls, seat)]
    seat_z = np.full((len(ctrls), sampler.L), np.nan)  # the seated frames' pelvis heights, for the seat settle
    for b, frames in enumerate(seated):
        for f, z in frames:
            seat_z[b, f] = z
    labels = np.stack([c.labels for c in ctrls])
    overlap = {} if pending is None else {  # the network crossfades into the pending frames as it denoises
        "lead": pending, "lead_weight": 1.0 - crossfade_weights(pending.shape[1]), "carried": carried}
    world = sampler.episode(context, labels, goals, object_poses=moved, generator=generator, **overlap)
    # dynamic objects count where they stand until the plan moves one (then the static scene only)
    sdf = None if sampler.scene_sdf is None else (sampler.scene_sdf_all if moved is None else sampler.scene_sdf)
    bodies = EpisodeBodies(world, context, lengths, labels, tuple(sampler.ckpt.vocabulary), sampler.ckpt.fps,
                           np.array([g.joint == "pelvis" for g in goals]), np.stack([c.reach_weight for c in ctrls]),
                           np.stack([c.reach_target for c in ctrls]), sdf, seat_z)
    raw: list[float] = []

    def network_bones(step: str, joints: np.ndarray) -> None:  # the network's bones, its pinned pelvis attached
        if step == "attach_pelvis":
            bl = bone_lengths_of(joints[:, sampler.k:].astype(np.float64))[..., 1:]  # (B, L - k, 23)
            raw.append(float(np.median(bl.std(1) / np.maximum(bl.mean(1), 1e-9))))

    cleanup = config.cleanup
    if pending is not None:  # the crossfade joins the episodes: the seam blend would add its own bend
        cleanup = replace(cleanup, seam=replace(cleanup.seam, enabled=False))
    world = run_cleanup(bodies, cleanup, observe=network_bones)
    return _Episode(world[:, sampler.k:], labels, np.stack([c.phases for c in ctrls]), goals, raw[0])


def sample_plan(ckpt: Checkpoint, sampler: EpisodeSampler, scene, walkmap, plan: Plan, *, num_samples: int = 1,
                seed: int = 0, max_seconds: float = 600.0, progress: bool = False,
                start_xy: np.ndarray | None = None, max_episodes: int | None = None,
                body: np.ndarray | None = None) -> SampleResult:
    """Roll ``plan`` out in ``scene`` for ``num_samples`` variations (one batch); see the module doc.
    ``body``: a standing frame (24, 3) world m whose body to use (``body_pose``; default the
    checkpoint's ``start_pose``).

    Raises ValueError when the plan is not done after ``max_seconds`` of motion; ``max_episodes``
    instead stops quietly after that many episodes (timing runs)."""
    from tqdm import tqdm

    if num_samples < 1:
        raise ValueError(f"num_samples must be >= 1, got {num_samples}")
    xy = np.asarray(plan.start if plan.start is not None else start_xy, dtype=np.float64)
    heading = float(plan.heading) if plan.heading is not None else 0.0
    phases = compile_plan(plan, scene, walkmap, xy, action_seconds(ckpt), ckpt.fps, vocabulary=ckpt.vocabulary,
                          heading=heading)
    controllers = [Controller(phases, ckpt.vocabulary, ckpt.L_epi, ckpt.k, ckpt.fps, _speed(ckpt),
                              reach=sampler.config.cleanup.reach, walkmap=walkmap) for _ in range(num_samples)]
    pose = start_pose(ckpt) if body is None else body_pose(body, "body")
    context = start_context(ckpt, xy, heading, num_samples, pose)
    lengths = bone_lengths_of(context[0, 0].astype(np.float64))
    sampler.hip_width = float(np.linalg.norm(context[0, 0, JOINT_INDEX["left_hip"], :2]
                                             - context[0, 0, JOINT_INDEX["right_hip"], :2]))
    N_A = len(ckpt.vocabulary)
    stand = np.zeros((ckpt.k, N_A), np.float32)
    if "stand" in ckpt.vocabulary:
        stand[:, ckpt.vocabulary.index("stand")] = 1.5
    frames, labels, phase = [context], [np.broadcast_to(stand, (num_samples,) + stand.shape)], \
        [np.full((num_samples, ckpt.k), -1)]
    g = torch.Generator().manual_seed(int(seed))
    seat = sit_offset(pose)
    overlap = sampler.config.overlap
    if overlap > ckpt.L_epi - ckpt.k - 1:
        raise ValueError(f"overlap {overlap} leaves no new frame to commit: an episode makes {ckpt.L_epi - ckpt.k}; "
                         f"use at most {ckpt.L_epi - ckpt.k - 1}")
    limit = int(np.ceil(max_seconds * ckpt.fps / (ckpt.L_epi - ckpt.k - overlap)))
    t0, episodes, starts, goals, cvs = 0.0, 0, [], [], []
    pending = None  # the last episode's uncommitted frames (B, overlap, 24, 3), to crossfade
    carried: tuple[tuple[Goal, ...], ...] = ()  # its goals due in those frames, for the next episode
    bar = tqdm(desc="sampling", unit="episode", disable=not progress, leave=False)
    while not all(c.done for c in controllers) and (max_episodes is None or episodes < max_episodes):
        if episodes >= limit:
            raise ValueError(f"the plan did not finish within {max_seconds:.0f} s of motion; the body does not "
                             f"reach its goals - check the plan or raise --max-seconds")
        tic = time.perf_counter()
        starts.append(sum(f.shape[1] for f in frames) - ckpt.k)
        context = frames[-1][:, -ckpt.k:]
        snapshots = [_snapshot(c) for c in controllers]
        ep = _step(sampler, controllers, context, labels[-1][:, -ckpt.k:], lengths, g, seat, pending, carried)
        new = ep.new
        n = new.shape[1]
        carried = ()
        if overlap and not all(c.done for c in controllers):  # commit all but the last `overlap` frames
            n -= overlap
            carried = _carried_goals(ep.goals, n, ckpt.L_epi, ckpt.k, overlap)
            for b, (c, snap) in enumerate(zip(controllers, snapshots)):
                _restore(c, snap)
                _advance(c, n, context[b, -1, PELVIS, :2])
            pending = new[:, n:]
        else:
            pending = None
        t0 += time.perf_counter() - tic
        frames.append(new[:, :n])
        labels.append(ep.labels[:, ckpt.k:ckpt.k + n])
        phase.append(ep.phase[:, ckpt.k:ckpt.k + n])
        end = starts[-1] + ckpt.L_epi - 1
        for b, gl in enumerate(ep.goals):
            f = end if gl.joint == "pelvis" else starts[-1] + gl.frame % ckpt.L_epi
            goals.append((f, b, gl.joint, np.asarray(gl.point)))
        cvs.append(ep.raw_cv)
        episodes += 1
        bar.update(1)
    bar.close()
    T = sum(f.shape[1] for f in frames)
    goals = [gl for gl in goals if gl[0] < T]  # a goal due in frames the last episode never made
    return SampleResult(np.concatenate(frames, 1), np.concatenate(labels, 1), np.concatenate(phase, 1), phases,
                        ckpt.fps, list(ckpt.vocabulary), episodes, t0, starts, goals,
                        float(np.median(cvs)) if cvs else float("nan"), seat, ckpt.k)


def stream(ckpt: Checkpoint, sampler: EpisodeSampler, scene, walkmap, plan: Plan, *, seed: int = 0,
           schedule: tuple[int, ...] = INCREMENTAL_SCHEDULE, body: np.ndarray | None = None
           ) -> Generator[np.ndarray, Plan | None, None]:
    """Yield (n, 24, 3) world frames as they are made, forever; ``send(plan)`` switches to a new
    plan from where the body is. After a (new) plan the first episodes commit ``schedule`` new
    frames each (2, 4, 8), then full episodes of L - k frames. When the plan is done the body
    stands (or holds its posture) where it is. ``body``: as in ``sample_plan``."""
    k, L = ckpt.k, ckpt.L_epi
    if any(not 1 <= n <= L - k for n in schedule):
        raise ValueError(f"schedule entries must be in [1, {L - k}], got {schedule}")
    xy = np.asarray(plan.start if plan.start is not None else (0.0, 0.0), dtype=np.float64)
    pose = start_pose(ckpt) if body is None else body_pose(body, "body")
    context = start_context(ckpt, xy, float(plan.heading or 0.0), 1, pose)
    lengths = bone_lengths_of(context[0, 0].astype(np.float64))
    prev = np.zeros((1, k, len(ckpt.vocabulary)), np.float32)
    g = torch.Generator().manual_seed(int(seed))
    seat = sit_offset(pose)

    def controller_for(p: Plan, at: np.ndarray, facing: float) -> Controller:
        return Controller(compile_plan(p, scene, walkmap, at, action_seconds(ckpt), ckpt.fps, vocabulary=ckpt.vocabulary,
                                       heading=facing), ckpt.vocabulary, L, k, ckpt.fps, _speed(ckpt),
                          reach=sampler.config.cleanup.reach, walkmap=walkmap)

    ctrl = controller_for(plan, xy, float(plan.heading or 0.0))
    todo = list(schedule)
    while True:
        n = todo.pop(0) if todo else L - k
        if ctrl.done:  # hold: an empty plan keeps the last posture label
            ctrl = Controller([Phase("act", ("stand",), frames=L)], ckpt.vocabulary, L, k, ckpt.fps, _speed(ckpt),
                              reach=sampler.config.cleanup.reach)
        snapshot = _snapshot(ctrl)
        ep = _step(sampler, [ctrl], context, prev, lengths, g, seat)
        new, lab = ep.new, ep.labels
        if n < L - k:  # commit only n frames: rewind the controller to what those frames consumed
            _restore(ctrl, snapshot)
            _advance(ctrl, n, context[0, -1, PELVIS, :2])
        out = new[:, :n]
        context = np.concatenate([context, out], 1)[:, -k:]
        prev = lab[:, k:k + n][:, -k:] if n >= k else np.concatenate([prev, lab[:, k:k + n]], 1)[:, -k:]
        sent = yield out[0]
        if sent is not None:
            ctrl = controller_for(sent, context[0, -1, PELVIS, :2].astype(np.float64), float(body_heading(context[0, -1])))
            todo = list(schedule)


def _carried_goals(goals: list[Goal], committed: int, L: int, k: int, overlap: int) -> tuple[tuple[Goal, ...], ...]:
    """Per sample, the episode's goals due in its ``overlap`` uncommitted frames, re-timed to the next
    episode (which starts ``committed`` new frames later and makes those frames again): its guidance
    keeps them (an overlapped episode's last frame, where its pelvis goal is due, is the next one's)."""
    out = []
    for g in goals:
        frame = (L - 1 if g.joint == "pelvis" else g.frame % L) - committed
        keep = k <= frame < k + overlap
        out.append((replace(g, frame=frame),) if keep else ())
    return tuple(out)


def _snapshot(ctrl: Controller) -> tuple:
    """What ``Controller.next`` advances: restore it with ``_restore`` to rewind an episode."""
    return ctrl.index, ctrl.elapsed, ctrl.walk_s, ctrl.body_s, ctrl.approach_tries, list(ctrl.releases)


def _restore(ctrl: Controller, snapshot: tuple) -> None:
    ctrl.index, ctrl.elapsed, ctrl.walk_s, ctrl.body_s, ctrl.approach_tries, releases = snapshot
    ctrl.releases = list(releases)


def _advance(ctrl: Controller, n: int, pelvis_xy: np.ndarray) -> None:
    """Advance a rewound controller by n frames (the committed part of an episode)."""
    k = ctrl.k
    saved = ctrl.L
    ctrl.L = k + n
    ctrl.next(pelvis_xy, np.zeros((k, len(ctrl.vocab)), np.float32))
    ctrl.L = saved
