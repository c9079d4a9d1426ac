"""Interaction tracking from body motion (iReplica §4): contacts -> trajectory -> objects.

``track(seq, scene, model)``:
1. per-hand contact probabilities and the interaction class from the pose windows (§4.2): one
   model with a class head, or one model per dof class {dof: model} (supp. §10.1,
   ``trumans.track.per_dof``: each interval takes the class of the model that fires);
2. threshold, gap filling (<= 0.5 s), contact intervals and hand-set segments (§4.2, supp. §10);
3. for each interval in time order whose class is a movable dof (slide | hinge | free): the
   nearest object of that dof within ``search_radius`` of the contacting hands (supp. §10.1;
   none -> the contact is a false positive and ignored; judged on the path as sensed, corrected
   by the anchors only, since the offset of earlier contacts is stale here; for a carried object,
   of the candidates within ``ambiguity`` of the nearest, the one that rests on a surface where the
   hands let go: ``trumans.track.object_choice``); its contact point p_c (the closest
   object point to the hand; for a free object taken from above, the footprint's centre: ``grasp_targets``)
   becomes a control point for the root path, which is bent to it by
   the bending-energy correction (§4.1 eqs. 1-2, with every control point so far and any anchors);
4. with the final corrected body, each interaction drives its object within its dof (supp. §10:
   two-hand / one-hand sliding, hinge, free), segment by segment, doors and drawers within their
   range (``clip_to_limits``); the object is released at the contact's end and stays where it was left,
   except a carried (free) object: it is taken when a hand comes within ``hold_reach`` of it, held
   on while it is carried up after the predicted contact ends, until it touches down on a surface
   (``trumans.track.release``), and settles upright on the surface under it (``trumans.track.support``).
   Which hands hold it is geometry's call as well as the network's (§4.2 takes the hand set from
   the per-hand contacts): both hands hold it for as long as both palms carry it between them
   (``two_hand_grip``), and a grip already under way when the contact starts (a box in the hands
   from the first frame) takes it where the grip began (``two_hand_take``, looked for up to
   ``GRIP_LOOKBACK_S`` before; its control point centres the object between the palms,
   ``object_choice.two_hand_targets``).
The result is a Sequence with the corrected joints / root and ``objects/<name>/pose`` for every
dynamic object of the scene, plus ``extra``: ``contact_prob (T, 2)``, ``contact_mask (T, 2)`` (the
predicted contacts without those with no surface within ``contact_reach`` of the hand, §4.2, and
with every frame a hand holds an object),
``root_correction (T, 2)`` (m) and ``interactions (N, 5)`` int64 rows, one per hand-set segment,
``[start, end, object index into extra['interaction_objects'], left, right]``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.ndimage import gaussian_filter1d

from trumans.scenes.scene import Scene, SceneObject
from trumans.track.model_io import ContactModels
from trumans.track.objects import (TWO_HAND_SPAN_M, dof_limits, free_motion, hand_points, two_hand_free_motion, hinge_motion, one_hand_motion, rotation_about_axis,
                                      rotation_angles, two_hand_motion)
from trumans.track.postprocess import ContactSegment, PostprocessConfig, contact_mask, contact_segments
from trumans.track.per_dof import predict_dof_contacts
from trumans.track.predictor import CLASSES, ContactPredictor, predict_contacts
from trumans.track.trajectory import TrajectoryConfig, correct_trajectory
from trumans.resample import interp_rotations, resample_times
from trumans.rotations import matrix_to_6d, sixd_to_matrix
from trumans.sequence import ObjectTrack, Sequence
from trumans.skeleton import JOINT_INDEX, forward_kinematics

from trumans.track.release import carried_release, lift_off
from trumans.track.support import SupportQuery
from trumans.track.object_choice import (ObjectQueries, choose_free_object, grasp_targets, object_candidates,
                                          release_support_gap, two_hand_targets)

__all__ = ["TrackerConfig", "AttachedContact", "TrackResult", "contact_probabilities", "interval_classes",
           "attach_detach", "attach_contact", "drive_object", "drive_contact", "clip_to_limits", "between_palms",
           "two_hand_grip", "two_hand_take", "with_both_hands", "track"]

_WRIST = (JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"])
PALMS_OUTSIDE_M = 0.08  # m, hand points holding a box between them are at most this much farther apart than its width
GRIP_SPAN_TOL_M = 0.06  # m, two hands holding one object between them keep their distance this near its value at the take
GRIP_MIN_S = 0.5  # s, ... for at least this long
GRIP_MOVE_M = 0.10  # m, ... while their midpoint moves this far (they carry it, not rest on it)
GRIP_LOOKBACK_S = 2.0  # s, a two-hand grip that holds at the predicted contact's start is looked for this far before it


@dataclass(frozen=True)
class TrackerConfig:
    """post: contact post-processing; trajectory: bending-energy correction; search_radius (m):
    object search around the hands at contact start (0.5 m in the paper); hand_radius (m): the
    hand point's distance to the surface it touches (the control point puts it there); ambiguity
    (m): free objects this much farther from the hands than the nearest one are candidates too,
    and the one that rests on a surface where the hands let go wins (``trumans.track.object_choice``;
    0 = the paper's nearest object);
    correct: run the contact-based trajectory correction (False = the ablation); predict_stride:
    one prediction window every that many frames (1 = the paper's centre-frame prediction; 3 is
    about 3x cheaper, see ``predict_contacts``); class_fallback: a contact of a movable class with no
    object of that class within ``search_radius`` takes the nearest object of the next most probable
    movable class (not in the paper, which ignores it; on real motion the class head calls a box
    lifted from the floor "slide" as often as "free", issue 36.6; False = the paper's rule); hold_reach (m): a carried object is taken only once a
    contacting hand point comes this near it (``_hold_while_carried``); contact_reach (m): an output
    contact (``extra['contact_mask']``) needs a surface of the scene this near the hand point on the
    corrected path (a localisation error of up to ~15 cm plus the hand's reach; §4.2 drops contacts
    with nothing near as false positives; also how near both hands must be to an object, before
    the contact's control point, for a two-hand grip under way to take it: ``two_hand_take``)."""

    post: PostprocessConfig = field(default_factory=PostprocessConfig)
    trajectory: TrajectoryConfig = field(default_factory=TrajectoryConfig)
    search_radius: float = 0.5
    hand_radius: float = 0.015
    ambiguity: float = 0.15
    correct: bool = True
    predict_stride: int = 3
    class_fallback: bool = True
    hold_reach: float = 0.12
    contact_reach: float = 0.25

    def __post_init__(self) -> None:
        if not self.hold_reach > 0 or not self.contact_reach > 0:
            raise ValueError(f"hold_reach and contact_reach must be > 0 (m), got {self.hold_reach}, {self.contact_reach}")
        if not self.search_radius > 0 or not self.hand_radius >= 0 or not self.ambiguity >= 0:
            raise ValueError(f"search_radius must be > 0, hand_radius and ambiguity >= 0 (m), got "
                             f"{self.search_radius}, {self.hand_radius}, {self.ambiguity}")


@dataclass(frozen=True)
class AttachedContact:
    """One contact interval attached to ``name`` (a scene object of dof ``dof``): frames
    [start, end), its hand-set segments, and the contact point (world, m) at its start."""

    name: str
    dof: str
    start: int
    end: int
    segments: tuple[ContactSegment, ...]
    contact_point: np.ndarray


@dataclass
class TrackResult:
    """sequence: the output; interactions; prob (T, 2) / mask (T, 2) per hand (the output
    ``extra['contact_mask']``); classes (N,) the
    class name of each union contact interval; correction (T, 2) m added to the root path."""

    sequence: Sequence
    interactions: list[AttachedContact]
    prob: np.ndarray
    mask: np.ndarray
    classes: list[str]
    correction: np.ndarray


def contact_probabilities(model: ContactModels, rotations: np.ndarray, fps: float,
                          stride: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(T, 24, 6) rotations at ``fps`` -> contact (T, 2) and class (T, C) probabilities (per-dof
    models {dof: model}: class scores, ``predict_dof_contacts``); the poses are resampled to the
    model's rate and the probabilities interpolated back."""
    rot = np.asarray(rotations, dtype=np.float32)
    if isinstance(model, ContactPredictor):
        mfps, predict = model.config.fps, lambda r: predict_contacts(model, r, stride=stride)
    else:
        if not model:
            raise ValueError("no contact model: give one model with a class head or {dof: model} for some dofs")
        rates = {m.config.fps for m in model.values()}
        if len(rates) != 1:
            raise ValueError(f"the per-dof contact models expect different frame rates {sorted(rates)}; retrain them alike")
        mfps, predict = rates.pop(), lambda r: predict_dof_contacts(model, r, stride=stride)
    if abs(fps - mfps) < 1e-9 or len(rot) < 2:
        return predict(rot)
    src = resample_times(len(rot), fps, mfps)
    rot_m = matrix_to_6d(interp_rotations(sixd_to_matrix(rot.astype(np.float64)), src)).astype(np.float32)
    prob, cls = predict(rot_m)
    t = np.arange(len(rot)) * (mfps / fps)  # original frames in model-frame coordinates
    interp = lambda p: np.stack([np.interp(t, np.arange(len(p)), p[:, k]) for k in range(p.shape[1])], 1)
    return interp(prob).astype(np.float32), interp(cls).astype(np.float32)


def interval_classes(class_prob: np.ndarray, segments: list[ContactSegment]) -> dict[int, str]:
    """Union interval index -> the class with the largest mean probability over its frames."""
    out: dict[int, str] = {}
    for i in sorted({s.interval for s in segments}):
        frames = np.concatenate([np.arange(s.start, s.end) for s in segments if s.interval == i])
        out[i] = CLASSES[int(class_prob[frames].mean(0).argmax())]
    return out


def _next_classes(class_prob: np.ndarray, segs: tuple[ContactSegment, ...], first: str) -> list[str]:
    """The movable classes other than ``first``, most probable over the segments' frames first.
    class_prob: (T, C) over ``CLASSES``."""
    frames = np.concatenate([np.arange(s.start, s.end) for s in segs])
    mean = class_prob[frames].mean(0)
    return [CLASSES[k] for k in np.argsort(-mean, kind="stable") if CLASSES[k] not in ("none", first)]


def _attach_window(n: int, fps: float, window_s: float = 1.0) -> int:
    """Frames at the start (and end) of an n-frame contact searched for attaching (detaching)."""
    return max(1, min(int(round(window_s * fps)), n // 2))


def attach_detach(hands: np.ndarray, dist_at_rest: np.ndarray, start: int, end: int, fps: float,
                  window_s: float = 1.0, approach_tol: float = 0.01,
                  attach: Literal["approach", "stop", "start"] = "approach") -> tuple[int, int]:
    """Refine a contact interval [start, end) to the frames the object is actually held (not in
    the paper; the contact labels switch on a few cm before the hand touches and off a few cm after
    it lets go, and the hands must not drag the object while reaching or retracting).
    hands: (n, k, 3) contacting hand points over the interval; dist_at_rest: (n,) their mean
    distance (m) to the object at its pose at ``start``. ``attach="approach"``: attach at the first
    frame within ``approach_tol`` of the closest approach in the first ``window_s`` (at most half
    the interval; the first, as a hand lifting an object slides along its side and gets no further
    from it); ``"stop"``: at the slowest frame of the hands in that window (a hand stops on a
    piece of furniture before it pushes or pulls; unlike the distance, the speed does not depend
    on the localisation offset); ``"start"``: at ``start`` (the hands already hold it:
    ``two_hand_take``). Detach after the slowest frame of the hands (speed smoothed over ~0.07 s)
    within the last ``window_s`` (the hand stops before it lets go). Returns (attach,
    detach) frames, start <= attach < detach <= end."""
    if attach not in ("approach", "stop", "start"):
        raise ValueError(f"attach must be 'approach', 'stop' or 'start', got {attach!r}")
    n = end - start
    w = _attach_window(n, fps, window_s)
    near = dist_at_rest[:w]
    first = start + int(np.argmax(near <= near.min() + approach_tol))
    if n < 3:
        return first, end
    # speed of the hands smoothed over ~0.07 s: tracked hands jitter by millimetres per frame, as much
    # as the hands move while they slow down to let go
    smooth = gaussian_filter1d(np.asarray(hands, np.float64), sigma=max(0.033 * fps, 0.5), axis=0, mode="nearest")
    speed = np.linalg.norm(np.gradient(smooth, axis=0), axis=-1).mean(-1)  # (n,) m/frame
    if attach == "start":
        first = start
    if attach == "stop":
        first = start + int(np.argmin(speed[:w]))
    lo = max(first - start + 1, n - w)
    detach = start + lo + int(np.argmin(speed[lo:])) + 1
    return first, max(detach, first + 1)


def _clip(segs: tuple[ContactSegment, ...], a: int, d: int) -> tuple[ContactSegment, ...]:
    return tuple(ContactSegment(max(s.start, a), min(s.end, d), s.hands, s.interval)
                 for s in segs if min(s.end, d) > max(s.start, a))


def drive_object(dof: str, seg: ContactSegment, hands: np.ndarray, wrist_rot: np.ndarray, wrist_pos: np.ndarray,
                 pose0: np.ndarray, axis: np.ndarray | None, hinge_point: np.ndarray | None,
                 width: float = 0.0) -> np.ndarray:
    """Motions (n, 4, 4) of an object over a segment (supp. §10). hands: (n, 2, 3) hand points;
    wrist_rot: (n, 2, 3, 3) / wrist_pos: (n, 2, 3) wrist world poses (a free object rides on the
    wrist's frame: the fingers move relative to it while grasping); pose0: the object's pose at the segment start;
    axis / hinge_point: object frame (slide direction or hinge); width: the free object's largest
    horizontal extent (m): two hands ``TWO_HAND_SPAN_M`` or more and at most ``PALMS_OUTSIDE_M`` more
    than that apart hold it between them (``two_hand_free_motion``), else it rides on the leading wrist."""
    used = [h for h in (0, 1) if seg.hands[h]]
    main = 1 if seg.hands[1] else 0  # the right hand leads when both hold on
    if dof == "hinge":
        return hinge_motion(hands[:, used].mean(1), pose0[:3, :3] @ hinge_point + pose0[:3, 3], pose0[:3, :3] @ axis)
    if dof == "slide":
        if axis is not None:  # along one direction (drawer): translation only
            return one_hand_motion(hands[:, used].mean(1), pose0[:3, :3] @ axis)
        if seg.two_handed:
            return two_hand_motion(hands[:, 0], hands[:, 1])
        return one_hand_motion(hands[:, main])
    if dof == "free":
        span = float(np.linalg.norm(hands[0, 0] - hands[0, 1]))
        if seg.two_handed and between_palms(span, width):  # a box between the palms
            return two_hand_free_motion(hands[:, 0], hands[:, 1])
        return free_motion(wrist_rot[:, main], wrist_pos[:, main])
    raise ValueError(f"cannot drive an object of dof {dof!r}; movable dofs are slide, hinge, free")


def between_palms(span: float, width: float) -> bool:
    """Can two hand points ``span`` m apart hold an object of largest horizontal extent ``width`` m
    between them (``drive_object``'s rule for a two-hand free segment): ``TWO_HAND_SPAN_M`` or more
    apart (closer hands hold one small object) and at most ``PALMS_OUTSIDE_M`` farther apart than it is wide."""
    return TWO_HAND_SPAN_M <= span <= width + PALMS_OUTSIDE_M


def two_hand_grip(hands: np.ndarray, dist: np.ndarray, centre: np.ndarray, width: float, fps: float, reach: float,
                  tol: float = GRIP_SPAN_TOL_M, min_s: float = GRIP_MIN_S, move: float = GRIP_MOVE_M) -> int:
    """How many frames from the take both hands hold a free object between them, whichever hands the
    contact network calls (0: not a two-hand grip). Not in the paper: iReplica takes the hand set
    of each contact segment from the network's per-hand contacts (§4.2) and moves a free object
    with the holding hand (§4.3, supp. §10); on real motion the network often calls a box carried
    between the palms one-handed (issue 36.6, CMU 111_36: the left hand only, for 11 s), and the
    box then rides on one wrist at the offset it was taken at, tens of cm from the hands. Geometry
    decides instead: both palms are on the object at the take and move rigidly with one another.

    hands: (n, 2, 3) the left / right hand points from the take frame on (index 0 = the take);
    dist: (2,) their distances (m) to the object's surface at the take; centre: (3,) the object's
    centre (world) at the take; width: its largest horizontal extent (m). A grip needs, at the
    take, both hands within ``reach`` of its surface, the centre between them along the line
    joining them, and hands that can hold it between them (``between_palms``). It lasts while their
    distance (smoothed over ~0.1 s) stays within ``tol`` of its value at the take (a hand that lets
    go or takes a new hold breaks it), and counts only when it lasts ``min_s`` or more while their
    midpoint moves ``move`` or more (carried, not two hands resting on it). Returns the grip's length
    in frames (<= n)."""
    h = np.asarray(hands, np.float64)
    n = len(h)
    if n < 2 or not (np.asarray(dist) <= reach).all():
        return 0
    axis = h[0, 0] - h[0, 1]
    span0 = float(np.linalg.norm(axis))
    if not between_palms(span0, width):
        return 0
    along = float((np.asarray(centre, np.float64) - h[0, 1]) @ axis) / span0
    if not 0.0 < along < span0:
        return 0  # the object is not between the hands
    span = gaussian_filter1d(np.linalg.norm(h[:, 0] - h[:, 1], axis=-1), sigma=max(0.05 * fps, 0.5), mode="nearest")
    off = np.flatnonzero(np.abs(span - span[0]) > tol)
    k = int(off[0]) if len(off) else n
    mid = h[:k].mean(1)
    if k < min_s * fps or np.linalg.norm(mid - mid[0], axis=-1).max() < move:
        return 0
    return k


def two_hand_take(queries: ObjectQueries, name: str, pose: np.ndarray, hands: np.ndarray, lo: int, s0: int,
                  fps: float, reach: float) -> int | None:
    """The first frame b in [lo, s0] from which both hands hold free object ``name`` (at rest at
    ``pose``) between them in one grip (``two_hand_grip``, within ``reach`` of its surface at b)
    that lasts past the predicted contact's start ``s0``; None if there is none. hands: (T, 2, 3)
    the hand points on the path corrected so far. Not in the paper: iReplica takes an object
    where the network's contact starts (§4.2) and holds it from there (§4.3). A box already
    carried between the palms when the motion begins (CMU 111_36, "walk and carry": in the hands
    from frame 0, the contact predicted from frame 30) has been carried 46 cm by then; taken
    there, the control point puts one hand on it where it stood and bends the body's path back by
    that much. The hands' grip tells when it was really taken: it is the contact's, from b on."""
    obj = queries.scene.objects[name]
    m = s0 - lo + 1
    if m < 1:
        return None
    H = np.asarray(hands[lo:], np.float64)
    _, d = queries.closest(name, pose, H[:m].reshape(-1, 3))
    d = d.reshape(m, 2)
    centre = pose[:3, :3] @ obj.mesh.bounds.mean(0) + pose[:3, 3]
    width = _width(obj)
    for b in np.flatnonzero((d <= reach).all(1)):
        if b + two_hand_grip(H[b:], d[b], centre, width, fps, reach) > m - 1:
            return lo + int(b)
    return None


def with_both_hands(segs: tuple[ContactSegment, ...], lo: int, hi: int) -> tuple[ContactSegment, ...]:
    """The contiguous segments ``segs`` of one contact with both hands holding on frames [lo, hi)
    (``two_hand_grip``), cut again into runs of a constant hand set (§4.2's segments)."""
    if hi <= lo or not segs:
        return segs
    s0, e0 = segs[0].start, segs[-1].end
    code = np.zeros(e0 - s0, np.int64)
    for sg in segs:
        code[sg.start - s0:sg.end - s0] = int(sg.hands[0]) + 2 * int(sg.hands[1])
    code[max(lo, s0) - s0:max(min(hi, e0), s0) - s0] = 3
    cut = np.flatnonzero(np.diff(code)) + 1
    bounds = np.r_[0, cut, len(code)]
    return tuple(ContactSegment(s0 + int(b0), s0 + int(b1), (bool(code[b0] & 1), bool(code[b0] & 2)), segs[0].interval)
                 for b0, b1 in zip(bounds[:-1], bounds[1:]) if code[b0])


def clip_to_limits(obj: SceneObject, poses: np.ndarray) -> np.ndarray:
    """World poses (n, 4, 4) of a hinged or axis-sliding object moved back within its range
    (``trumans.track.objects.dof_limits``, from the scene pose: a door's opening angle, a drawer's travel);
    poses within range and objects without limits are returned unchanged. The hands alone push a
    drawer past closed or a door through its frame whenever the localisation drifts during the
    contact; the dof's end stop is where the object really stops (extends the dof model of iReplica
    supp. §10, which has no range)."""
    lo, hi = dof_limits(obj)
    poses = np.asarray(poses, dtype=np.float64)
    if obj.dof not in ("hinge", "slide") or obj.axis is None or not (np.isfinite(lo) or np.isfinite(hi)):
        return poses
    axis = obj.pose[:3, :3] @ obj.axis
    if obj.dof == "hinge":
        point = obj.pose[:3, :3] @ obj.hinge_point + obj.pose[:3, 3]
        angle = rotation_angles(poses @ np.linalg.inv(obj.pose), axis)
        return rotation_about_axis(np.clip(angle, lo, hi) - angle, axis, point) @ poses
    travel = (poses[:, :3, 3] - obj.pose[:3, 3]) @ axis
    out = poses.copy()
    out[:, :3, 3] += (np.clip(travel, lo, hi) - travel)[:, None] * axis
    return out


def drive_contact(it: AttachedContact, scene: Scene, poses: dict[str, np.ndarray], joints: np.ndarray,
                  wrist_rot: np.ndarray, support: SupportQuery | None = None) -> None:
    """Apply interaction ``it`` to ``poses[it.name]`` in place: driven during its segments, then
    released where it was left; with ``support``, a free object let go before the last frame comes
    to rest upright on the surface under it (``SupportQuery.rest_pose``: nothing floats after a
    put-down). joints: (T, 24, 3); wrist_rot: (T, 2, 3, 3)."""
    obj = scene.objects[it.name]
    track = poses[it.name]
    for seg in it.segments:
        s, e = seg.start, seg.end
        M = drive_object(it.dof, seg, hand_points(joints[s:e]), wrist_rot[s:e], joints[s:e][:, list(_WRIST)], track[s],
                         obj.axis, obj.hinge_point, _width(obj))
        track[s:e] = clip_to_limits(obj, M @ track[s])
        track[e:] = track[e - 1]
    e = it.segments[-1].end
    if support is not None and it.dof == "free" and e < len(track):
        track[e:] = support.rest_pose(it.name, track[e - 1], {n: p[e] for n, p in poses.items() if n != it.name})


def attach_contact(queries: ObjectQueries, name: str, pose: np.ndarray, span: np.ndarray,
                   segs: tuple[ContactSegment, ...], s0: int, fps: float,
                   hand_radius: float, attach: Literal["approach", "stop", "start"] | None = None
                   ) -> tuple[tuple[ContactSegment, ...], int, np.ndarray, np.ndarray]:
    """A contact starting at frame ``s0`` attached to ``name`` (at ``pose``): its segments clipped to
    the held frames, the attach frame, and the contact points p_c (k, 3) with their targets
    ``hand_radius`` off them (k, 3) at that frame. span: (n, k, 3) contacting hand points. The
    attach frame is found on the hands' distance to the object's surface, or to its declared
    ``grasp_point`` (meta, object frame) when it has one: a hand reaching down over a small object
    (a mouse) stays about as near its top while it is still moving in, and would drag it along.
    attach: ``attach_detach``'s rule (None: "stop" for a sliding object, else "approach")."""
    near, dist, target = queries.contact_target(name, pose, span.reshape(-1, 3), hand_radius)
    meta = queries.scene.objects[name].meta
    if "grasp_point" in meta:  # held when the hand is there, not when it first comes near a surface
        grasp = pose[:3, :3] @ np.asarray(meta["grasp_point"], np.float64).reshape(3) + pose[:3, 3]
        dist = np.linalg.norm(span.reshape(-1, 3) - grasp, axis=-1)
    # a sliding object (furniture, a drawer) is taken when the hand stops on it: the measured
    # distance to it at rest is off by the localisation error (a chair's pull began 0.6 s late)
    mode = attach or ("stop" if queries.scene.objects[name].dof == "slide" else "approach")
    a, d_end = attach_detach(span, dist.reshape(len(span), -1).mean(1), s0, s0 + len(span), fps, attach=mode)
    return _clip(segs, a, d_end), a, near.reshape(span.shape)[a - s0], target.reshape(span.shape)[a - s0]


def _release_gap(queries: ObjectQueries, name: str, poses: dict[str, np.ndarray], segs: tuple[ContactSegment, ...],
                 span: np.ndarray, s0: int, fps: float, joints: np.ndarray, wrist_rot: np.ndarray,
                 hand_radius: float) -> float:
    """``release_support_gap`` of free object ``name`` carried by this contact and let go where the
    hands let go; the other objects are where the interactions so far left them."""
    held, _, closest, _ = attach_contact(queries, name, poses[name][s0], span, segs, s0, fps, hand_radius)
    trial = {name: poses[name].copy()}
    drive_contact(AttachedContact(name, "free", held[0].start, held[-1].end, held, closest.mean(0)), queries.scene,
                  trial, joints, wrist_rot)
    e = held[-1].end - 1
    others = {n: o.pose for n, o in queries.scene.objects.items() if o.dof == "static"}
    others.update({n: p[e] for n, p in poses.items() if n != name})
    return release_support_gap(queries, name, trial[name][e], others)


def _width(obj: SceneObject) -> float:
    """An object's largest horizontal extent (m) in its own frame."""
    return float((obj.mesh.bounds[1] - obj.mesh.bounds[0])[:2].max())


def _ride(obj: SceneObject, seg: ContactSegment, a: int, b: int, joints: np.ndarray, wrist_rot: np.ndarray,
          pose0: np.ndarray) -> np.ndarray:
    """Poses (b - a, 4, 4) of free object ``obj`` taken at ``pose0`` on frame ``a`` and held as in
    segment ``seg`` (``drive_object``: between two hands holding it between them, else on the leading wrist)."""
    return drive_object("free", seg, hand_points(joints[a:b]), wrist_rot[a:b], joints[a:b][:, list(_WRIST)], pose0,
                        None, None, _width(obj)) @ pose0


def _hold_while_carried(support: SupportQuery, queries: ObjectQueries, name: str, poses: dict[str, np.ndarray],
                        segs: tuple[ContactSegment, ...], a: int, contact_end: int, joints: np.ndarray,
                        wrist_rot: np.ndarray, fps: float, reach: float) -> tuple[ContactSegment, ...] | None:
    """The held segments of free object ``name`` attached at frame ``a`` (joints: (T, 24, 3) with this
    contact's correction): started at its lift-off when riding from ``a`` would push it into its
    support (``trumans.track.release.lift_off``), or later at the first frame a contacting hand point
    is within ``reach`` m of it (an object rides on the hand at the offset it is taken at, so one
    taken from farther would be held with nothing in the hand); the last segment run on to the frame
    the hands can let it go (``carried_release``: a contact that ends while the object is carried up
    continues until it touches down on a surface, or to the end); both hands hold it for as long
    as both palms, within ``reach`` of it at the take, carry it between them (``two_hand_grip``),
    whichever hands the contact calls. None when no hand comes within ``reach`` of it: the contact
    does not take it."""
    last = segs[-1]
    others = {n: p[contact_end - 1] for n, p in poses.items() if n != name}
    ride = _ride(support.scene.objects[name], last, a, last.end, joints, wrist_rot, poses[name][a])
    a = a + lift_off(support.gaps(name, ride, others), last.end - 1 - a)
    hands = hand_points(joints[a:last.end])  # (n, 2, 3); the object is at rest until it is taken
    used = [h for h in (0, 1) if any(sg.hands[h] for sg in segs)]
    _, dist = queries.closest(name, poses[name][a], hands[:, used].reshape(-1, 3))
    near = np.flatnonzero(dist.reshape(len(hands), -1).min(1) <= reach)
    if not len(near):
        return None
    a += int(near[0])
    obj = support.scene.objects[name]
    held = hand_points(joints[a:])  # (T - a, 2, 3)
    _, d0 = queries.closest(name, poses[name][a], held[0])
    centre = poses[name][a, :3, :3] @ obj.mesh.bounds.mean(0) + poses[name][a, :3, 3]
    both = a + two_hand_grip(held, d0, centre, _width(obj), fps, reach)  # both hands hold it on [a, both)
    segs = with_both_hands(_clip(segs, a, last.end), a, both)
    last = segs[-1]
    ride = _ride(obj, last, a, len(joints), joints, wrist_rot, poses[name][a])
    contact_end = max(contact_end, last.end)
    end = carried_release(support, name, ride, a, last.end, contact_end, others, fps)
    if end > last.end:
        segs = segs[:-1] + (ContactSegment(last.start, end, last.hands, last.interval),)
    return with_both_hands(segs, a, both)


def _drive_all(interactions: list[AttachedContact], scene: Scene, base: dict[str, np.ndarray], joints: np.ndarray,
               wrist_rot: np.ndarray, support: SupportQuery | None = None) -> dict[str, np.ndarray]:
    poses = {n: p.copy() for n, p in base.items()}
    for it in interactions:
        drive_contact(it, scene, poses, joints, wrist_rot, support)
    return poses


def track(seq: Sequence, scene: Scene, model: ContactModels, config: TrackerConfig = TrackerConfig(),
          anchors: tuple[np.ndarray, np.ndarray] | None = None) -> TrackResult:
    """Track interactions (module doc). model: a contact predictor with a class head or {dof: model};
    seq: body motion with ``rotations`` (T, 24, 6) and joints in
    the scene's frame; scene: its objects' dofs and initial poses; anchors: optional (frames (K,),
    root xy (K, 2)) known positions (e.g. visual localisation) used as extra control points."""
    if seq.rotations is None:
        raise ValueError("the sequence has no 'rotations'; the contact predictor needs local joint rotations "
                         "(fit them from joints with trumans.ik.fit.fit_rotations)")
    T, fps = seq.num_frames, float(seq.fps)
    a_frames = np.zeros(0, np.int64) if anchors is None else np.asarray(anchors[0]).astype(np.int64).ravel()
    a_xy = np.zeros((0, 2)) if anchors is None else np.asarray(anchors[1], np.float64).reshape(-1, 2)
    if len(a_frames) != len(a_xy) or (len(a_frames) and (a_frames.min() < 0 or a_frames.max() >= T)):
        raise ValueError(f"anchors must be frames (K,) in [0, {T - 1}] with positions (K, 2), got "
                         f"{a_frames.shape} / {a_xy.shape}")
    prob, class_prob = contact_probabilities(model, seq.rotations, fps, config.predict_stride)
    mask = contact_mask(prob, fps, config.post)
    segments = contact_segments(mask)
    cls = interval_classes(class_prob, segments)

    joints0 = np.asarray(seq.joints, np.float64)
    root0 = joints0[:, 0, :2]
    _, G = forward_kinematics(sixd_to_matrix(np.asarray(seq.rotations, np.float64)), np.zeros((T, 3)))
    wrist_rot = G[:, list(_WRIST)]  # (T, 2, 3, 3)
    base = {n: np.tile(o.pose, (T, 1, 1)) for n, o in scene.objects.items() if o.dof != "static"}
    queries = ObjectQueries(scene)

    def corrected(c_frames: list[int], c_xy: list[np.ndarray]) -> np.ndarray:
        frames = np.r_[a_frames, np.asarray(c_frames, np.int64)].astype(np.int64)
        pts = np.concatenate([a_xy, np.asarray(c_xy).reshape(-1, 2)])
        return correct_trajectory(root0, frames, pts, fps, config.trajectory) - root0

    corr = corrected([], [])
    joints_sel = joints0.copy()
    joints_sel[:, :, :2] += corr[:, None]  # the sensors' path with the anchors only: objects are chosen on it
    interactions: list[AttachedContact] = []
    c_frames: list[int] = []
    c_xy: list[np.ndarray] = []
    poses = {n: p.copy() for n, p in base.items()}
    support = SupportQuery(scene)
    held_until = 0  # a carried object is in the hands until this frame: later contacts are its own
    for i in sorted(cls):
        if cls[i] == "none":
            continue  # a contact with the static scene: nothing to drive
        segs = tuple(s for s in segments if s.interval == i)
        s0 = segs[0].start
        if s0 < held_until:
            continue  # the hands still carry an object (the reach that puts it down)
        joints = joints0.copy()
        joints[:, :, :2] += corr[:, None]
        e1 = segs[-1].end
        used = [h for h in (0, 1) if segs[0].hands[h]]
        span = hand_points(joints[s0:e1])[:, used]  # (n, k, 3) contacting hand points
        # choose the object on the path without earlier contacts' control points: their offset is
        # only known at those contacts and, carried here, can bring the hands nearer a wrong object
        # whose control point would then confirm the mismatch (issue 12, seed 1: 3.5 m off)
        reach = hand_points(joints_sel[s0:e1])[:, used][:_attach_window(len(span), fps)]
        cands = object_candidates(queries, poses, s0, reach, cls[i], config.search_radius)
        if not cands and config.class_fallback:
            for other in _next_classes(class_prob, segs, cls[i]):
                cands = object_candidates(queries, poses, s0, reach, other, config.search_radius)
                if cands:
                    cls[i] = other
                    break
        if not cands:
            continue  # no object of that class near the hands: a false positive (§4.1)
        name = cands[0][0]
        if cls[i] == "free" and len(cands) > 1 and e1 < T:
            gaps = {n: _release_gap(queries, n, poses, segs, span, s0, fps, joints, wrist_rot, config.hand_radius)
                    for n, d in cands if d <= cands[0][1] + config.ambiguity}
            name = choose_free_object(cands, gaps, config.ambiguity)
        mode = None
        if cls[i] == "free":  # both hands already hold it between them: taken by both, where the grip began
            lo = max(held_until, s0 - int(round(GRIP_LOOKBACK_S * fps)), 0)
            b = two_hand_take(queries, name, poses[name][s0], hand_points(joints), lo, s0, fps, config.contact_reach)
            if b is not None:
                segs = with_both_hands((ContactSegment(b, s0, (True, True), i),) * (b < s0) + segs, b, s0 + 1)
                s0, used, mode = b, [0, 1], "start"
                span = hand_points(joints[s0:e1])
        segs, a, closest, goal = attach_contact(queries, name, poses[name][s0], span, segs, s0, fps, config.hand_radius,
                                                mode)
        if mode == "start":  # held between the hands: centred between them
            p0 = poses[name][s0]
            goal = two_hand_targets(goal, span[a - s0], p0[:3, :3] @ scene.objects[name].mesh.bounds.mean(0) + p0[:3, 3])
        elif cls[i] == "free":
            goal = grasp_targets(goal, span[a - s0], np.asarray(scene.objects[name].mesh.vertices), poses[name][s0])
        shift = (goal - span[a - s0])[:, :2]
        step = shift.mean(0) if config.correct else np.zeros(2)
        # until the joint solve below, the new offset holds from this contact on (and before the
        # first one when nothing else pins the start)
        corr_new = corr.copy()
        corr_new[a if (c_frames or len(a_frames)) else 0:] += step
        joints[:, :, :2] = joints0[:, :, :2] + corr_new[:, None]
        if cls[i] == "free":
            segs = _hold_while_carried(support, queries, name, poses, segs, a, e1, joints, wrist_rot, fps,
                                       config.hold_reach)
            if segs is None:
                continue  # no hand comes near it: not taken (nor a control point)
            held_until = segs[-1].end
        interactions.append(AttachedContact(name, cls[i], segs[0].start, segs[-1].end, segs, closest.mean(0)))
        if config.correct:
            c_frames.append(a)
            c_xy.append(root0[a] + corr[a] + step)
            corr = corr_new
        drive_contact(interactions[-1], scene, poses, joints, wrist_rot, support)

    if c_frames:
        corr = corrected(c_frames, c_xy)  # eq. 2 with every control point
    joints = joints0.copy()
    joints[:, :, :2] += corr[:, None]
    poses = _drive_all(interactions, scene, base, joints, wrist_rot, support)
    names = sorted({it.name for it in interactions})
    rows = np.array([[seg.start, seg.end, names.index(it.name), int(seg.hands[0]), int(seg.hands[1])]
                     for it in interactions for seg in it.segments], dtype=np.int64).reshape(-1, 5)
    root_pos = None
    if seq.root_pos is not None:
        root_pos = np.asarray(seq.root_pos, np.float64).copy()
        root_pos[:, :2] += corr
    extra = dict(seq.extra)
    # §4.2: a contact with no surface within contact_reach of the hand is a false positive, and a
    # hand holding an object is in contact for as long as it holds it (the run-on of a carry)
    near = queries.surface_distance(hand_points(joints), poses) <= config.contact_reach  # (T, 2)
    mask = mask & near
    for it in interactions:
        for seg in it.segments:
            mask[seg.start:seg.end] |= np.asarray(seg.hands)
    extra.update(contact_prob=prob, contact_mask=mask, root_correction=corr.astype(np.float32), interactions=rows,
                 interaction_objects=np.asarray(names, dtype=np.str_))
    out = Sequence(
        joints=joints.astype(np.float32), fps=fps, rotations=seq.rotations, root_pos=root_pos, actions=seq.actions,
        action_names=list(seq.action_names), contacts=seq.contacts, scene=seq.scene,
        objects={n: ObjectTrack(pose=p.astype(np.float32), category=scene.objects[n].category) for n, p in poses.items()
                 if scene.objects[n].dynamic},
        extra=extra,
    )
    return TrackResult(out, interactions, prob, mask, [cls[i] for i in sorted(cls)], corr)
