"""Small objects fitted to real clips where hands pick something up and put it down (issue 9 §1).

Detection, from the motion (the CMU description only says which clips to search, ``HINT_WORDS``):
a *reach down* is a run of frames where the lower palm point (``hands.palm_points``) is below
``HANDLE_ZONE_M`` and gets below ``REACH_DOWN_M`` (hanging arms keep the palms at 0.8-0.9 m); its
lowest frame is the grasp / release moment. The reaching hand is the lower one, joined by the other
when that one is within ``BOTH_HANDS_DZ_M`` of it and ``BOX_MIN_SPAN_M`` or more away: two hands
lift a box between them. Reaches alternate: the first picks an object up, the next puts it down,
the next picks up (the same object when the hand comes within ``SAME_OBJECT_M`` of it, else a new
one), ...; two hands also put a box down where they open (palms ``RELEASE_SPREAD_M`` farther
apart than at the grasp: set on a support at that height) - unless the palms then stay steadily
apart at carry height for a second (a new grip on the box: a carry that walks off with the box held
wider, CMU 111_36); an object never put down is carried
to the clip's end. A clip described as carrying with no reach down whose palms stay
``BOX_MIN_SPAN_M`` or more and steadily (``STEADY_SPAN_M``) apart, above ``CARRY_ABOVE_M``, on
``CARRY_SHARE`` of its frames carries a box from its first frame (``carried_from_start``), as wide
as the palms' median distance over the carry (``_carry_grip``), not their distance on the first frame.

The object: one hand -> a bottle (``trumans.scenes.furniture.small_object``) gripped from the side, its
grasp point ``PALM_GAP`` from the palm away from the body; two hands -> a box (category "box")
between the palms, ``PALM_GAP`` inside each, reaching ``BOX_BEHIND_M`` behind the palms' line,
held at ``GRIP_SHARE`` of its height. It stands on the floor, or on a fitted support (a "table"
box on legs) when its bottom would be ``SUPPORT_MIN_M`` or more above the floor.

Pose track (T, 4, 4) world-from-object (docs/conventions.md): static before the pick-up, rigid with the
holding frame while carried (one hand: the wrist's global rotation at the palm point, the
``hands.core`` convention; two hands: origin at the palms' midpoint, y from the right palm to the
left one, z up), static after the put-down (the carried pose at release set upright on the floor
or a fitted support; ``HandledObjects.release_jump_m`` says how far that moves it). A put-down made
by the other hand takes the object over where the palms come closest (within ``HANDOVER_M``).
Labels (``SYNTH_ACTIONS``): ``pick_up`` on the pick reach, ``carry`` between, ``put_down`` on the
put reach; ``grasp`` flags (T, 2) the holding hands from the grasp to the release frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from trumans.scenes.furniture import small_object, yaw_pose
from trumans.scenes.scene import SceneObject

from trumans.actions import ActionInterval
from trumans.motion_labels import segments
from trumans.rotations import unit
from trumans.scene_fit import box_object
from trumans.skeleton import JOINT_INDEX
from .hands.core import PALM_GAP, inv_h, palm_points, to_h

__all__ = ["HINT_WORDS", "Reach", "HandledObjects", "hinted", "find_reaches", "holding_frames", "fit_handled_objects",
           "handled_footprints"]

HINT_WORDS = ("pick", "carry", "set down", "put down", "lift", "box", "basket", "suitcase")
HANDLE_ZONE_M = 0.70  # m, palm height below which a hand is handling something low
REACH_DOWN_M = 0.60  # m, a reach down gets the palm below this
BOTH_HANDS_DZ_M = 0.15  # m, the other palm this close in height reaches too
BOX_MIN_SPAN_M = 0.10  # m, two palms closer than this hold one small object (the lower hand's)
BOX_WIDTH_M = (0.10, 0.60)  # m, between the palms
BOX_HEIGHT_M = (0.12, 0.45)  # m
BOX_DEPTH_M = 0.25  # m, away from the body
BOX_BEHIND_M = 0.06  # m, the box reaches this far behind the palms' line (towards the body)
GRIP_SHARE = 0.6  # the palms hold a box at this share of its height
SUPPORT_MIN_M = 0.15  # m, an object whose bottom would be this high stands on a fitted support
SUPPORT_SIZE_M = 0.35  # m, side of a fitted support's square top
SUPPORT_MARGIN_M = 0.03  # m, a support shrunk out of the body's way reaches this far around the object
SAME_OBJECT_M = 0.30  # m, a pick this close (horizontally) to a put-down object takes that one again
HANDOVER_M = 0.15  # m, palms this close can pass an object from one hand to the other
RELEASE_SPREAD_M = 0.10  # m, two palms this much farther apart than at the grasp have let the box go
RELEASE_HALF_S = 0.5  # s, a put-down by opening the hands spans this much either side of it
STEADY_SPAN_M = 0.03  # m, std of the palm distance of two hands that hold one box
CARRY_ABOVE_M = 0.95  # m, palms above this hold something up (hanging arms: 0.8-0.9 m)
CARRY_SHARE = 0.8  # share of frames the palms hold a box up, for a carry from the first frame
FOOTPRINT_EVERY = 10  # frames between the carried poses whose footprints are kept free of furniture
UP = np.array([0.0, 0.0, 1.0])
LEFT, RIGHT = 0, 1


@dataclass(frozen=True)
class Reach:
    """A reach down on frames [start, end), lowest at ``frame``, by ``hands`` (0 left, 1 right);
    ``in_hand``: not a reach but a carry already under way at the clip's first frame."""

    start: int
    end: int
    frame: int
    hands: tuple[int, ...]
    in_hand: bool = False


@dataclass
class HandledObjects:
    """The fit of one clip: dynamic ``objects`` (at their first-frame pose) with ``tracks`` (name ->
    (T, 4, 4)), the fitted ``supports`` (static), action ``intervals``, ``grasp`` (T, 2) bool
    (left, right hand holds), the ``reaches`` found and ``release_jump_m`` per put-down (m, how far
    the object's centre moves when set upright at its release)."""

    objects: list[SceneObject] = field(default_factory=list)
    tracks: dict[str, np.ndarray] = field(default_factory=dict)
    supports: list[SceneObject] = field(default_factory=list)
    intervals: list[ActionInterval] = field(default_factory=list)
    grasp: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), bool))
    reaches: list[Reach] = field(default_factory=list)
    release_jump_m: list[float] = field(default_factory=list)


def hinted(description: str) -> bool:
    """Does a CMU description name picking up / carrying (``HINT_WORDS``)?"""
    d = description.lower()
    return any(w in d for w in HINT_WORDS)


def find_reaches(joints: np.ndarray) -> list[Reach]:
    """Reaches down (module doc) of joints (T, 24, 3) m, in time order."""
    palms = palm_points(np.asarray(joints, np.float64))  # (T, 2, 3)
    z = palms[..., 2]
    low = z.min(axis=1)
    out = []
    for s, e in segments(low < HANDLE_ZONE_M):
        m = s + int(np.argmin(low[s:e]))
        if low[m] >= REACH_DOWN_M:
            continue
        first = int(np.argmin(z[m]))
        other = 1 - first
        both = z[m, other] < REACH_DOWN_M and z[m, other] - z[m, first] < BOTH_HANDS_DZ_M and \
            np.linalg.norm(palms[m, 0] - palms[m, 1]) >= BOX_MIN_SPAN_M
        out.append(Reach(s, e, m, (LEFT, RIGHT) if both else (first,)))
    return out


def carried_from_start(joints: np.ndarray) -> Reach | None:
    """A two-hand carry under way from the first frame (module doc), or None. joints (T, 24, 3) m."""
    palms = palm_points(np.asarray(joints, np.float64))
    d = np.linalg.norm(palms[:, 0] - palms[:, 1], axis=-1)
    up = (palms[..., 2] > CARRY_ABOVE_M).all(axis=1)
    if d.min() < BOX_MIN_SPAN_M or d.std() > STEADY_SPAN_M or up.mean() < CARRY_SHARE:
        return None
    return Reach(0, 0, 0, (LEFT, RIGHT), in_hand=True)


def holding_frames(joints: np.ndarray, wrist_rot: np.ndarray, hands: tuple[int, ...]) -> np.ndarray:
    """(T, 4, 4) world frames that a held object moves rigidly with (module doc). joints (T, 24, 3) m;
    wrist_rot (T, 2, 3, 3) global rotations of the left / right wrist."""
    palms = palm_points(np.asarray(joints, np.float64))
    if len(hands) == 1:
        return to_h(np.asarray(wrist_rot, np.float64)[:, hands[0]], palms[:, hands[0]])
    y = unit(palms[:, LEFT] - palms[:, RIGHT])
    z = unit(UP - (y @ UP)[:, None] * y)
    return to_h(np.stack([np.cross(y, z), y, z], axis=-1), palms.mean(axis=1))


def _away(joints: np.ndarray, frame: int, point: np.ndarray) -> np.ndarray:
    """(2,) unit horizontal direction from the pelvis to ``point`` at ``frame`` (the body's heading
    from its hips when the point is right above the pelvis)."""
    J = JOINT_INDEX
    d = point[:2] - joints[frame, J["pelvis"], :2]
    if np.linalg.norm(d) > 0.05:
        return d / np.linalg.norm(d)
    left = joints[frame, J["left_hip"], :2] - joints[frame, J["right_hip"], :2]
    return unit(np.array([left[1], -left[0], 0.0]))[:2]


def _box(name: str, width: float, height: float) -> SceneObject:
    """A box (BOX_DEPTH_M, width, height) m, origin at its bottom centre; palms on its +-y sides."""
    mesh = trimesh.creation.box(extents=(BOX_DEPTH_M, width, height))
    mesh.apply_translation((0.0, 0.0, height / 2))
    meta = {"size": [BOX_DEPTH_M, width, height], "grasp_points": [[0.0, width / 2, GRIP_SHARE * height],
                                                                   [0.0, -width / 2, GRIP_SHARE * height]],
            "support": "", "fitted": "picked up with both hands"}
    return SceneObject(name, "box", mesh, dof="free", dynamic=True, meta=meta)


def _new_object(name: str, joints: np.ndarray, reach: Reach, rng: np.random.Generator,
                grip: float | None = None) -> tuple[SceneObject, float]:
    """The object grasped at ``reach`` and its bottom height (m, before choosing floor or support);
    its pose puts the grasp at the palm(s) (module doc). grip: the palms' distance (m) a box is
    sized by (``_carry_grip``); None: their distance at ``reach.frame``."""
    palms = palm_points(joints[reach.frame])  # (2, 3)
    if len(reach.hands) == 1:
        palm = palms[reach.hands[0]]
        obj = small_object(rng, name, "bottle")
        obj.meta["fitted"] = "picked up with one hand"
        gx, _, gz = obj.meta["grasp_point"]
        u = _away(joints, reach.frame, palm)  # the object's +x (grasped side) faces the body
        xy = palm[:2] + u * (gx + PALM_GAP)
        obj.pose = yaw_pose(float(xy[0]), float(xy[1]), float(np.arctan2(-u[1], -u[0])))
        return obj, float(palm[2] - gz)
    across = palms[LEFT] - palms[RIGHT]
    width = float(np.clip((np.linalg.norm(across) if grip is None else grip) - 2 * PALM_GAP, *BOX_WIDTH_M))
    mid = palms.mean(axis=0)
    height = float(np.clip(mid[2] / GRIP_SHARE, *BOX_HEIGHT_M))
    obj = _box(name, width, height)
    a = unit(np.array([across[0], across[1], 0.0]))[:2]
    fwd = np.array([a[1], -a[0]])  # the body's left turned -90 deg
    if fwd @ _away(joints, reach.frame, mid) < 0:
        fwd = -fwd
    xy = mid[:2] + fwd * (BOX_DEPTH_M / 2 - BOX_BEHIND_M)
    obj.pose = yaw_pose(float(xy[0]), float(xy[1]), float(np.arctan2(fwd[1], fwd[0])))
    return obj, float(mid[2] - GRIP_SHARE * height)


def _stand(obj: SceneObject, pose: np.ndarray, bottom: float, supports: list[SceneObject],
           joints: np.ndarray, frame: int) -> tuple[np.ndarray, str]:
    """``pose`` upright (its yaw kept) on the floor, or on a new fitted support (appended to
    ``supports``) when ``bottom`` >= SUPPORT_MIN_M: a square top of ``SUPPORT_SIZE_M`` whose near
    edge is under the object's near side (the body stands there), shrunk to the object's footprint
    plus ``SUPPORT_MARGIN_M`` where a joint of joints (T, 24, 3) m would be inside it on some frame.
    Returns the standing pose and the support's name ("" = floor)."""
    yaw = float(np.arctan2(pose[1, 0], pose[0, 0]))
    x, y = float(pose[0, 3]), float(pose[1, 3])
    if bottom < SUPPORT_MIN_M:
        return yaw_pose(x, y, yaw, 0.0), ""
    u = _away(joints, frame, pose[:3, 3])
    near = float(np.abs(obj.mesh.bounds[:, :2]).max())  # the object's half extent, m
    small = 2 * (near + SUPPORT_MARGIN_M)
    name = f"fit_support_{len(supports)}"
    for side in (max(SUPPORT_SIZE_M, small), small):
        c = np.array([x, y]) + u * (side / 2 - near - SUPPORT_MARGIN_M)
        meta = {"surface_height": bottom, "surface_size": [side, side], "surface_center": [0.0, 0.0, bottom],
                "fitted": f"under {obj.name}"}
        sup = box_object(name, "table", float(c[0]), float(c[1]), float(np.arctan2(-u[1], -u[0])), side, side,
                         bottom, meta, legs=True, avoid=joints)
        if not sup.world_mesh().contains(joints.reshape(-1, 3)).any():
            break
    supports.append(sup)
    return yaw_pose(x, y, yaw, bottom), name


def _upright(obj: SceneObject, pose: np.ndarray) -> tuple[np.ndarray, float]:
    """A carried pose set upright about the object's centre: (pose with that centre, yaw kept and
    the bottom at z = 0 for now, the bottom height m)."""
    h = float(obj.meta["size"][2])
    c = pose[:3, :3] @ np.array([0.0, 0.0, h / 2]) + pose[:3, 3]
    yaw = float(np.arctan2(pose[1, 0], pose[0, 0]))
    return yaw_pose(float(c[0]), float(c[1]), yaw, 0.0), float(c[2] - h / 2)


def _handover(joints: np.ndarray, a: int, b: int) -> int | None:
    """Frame in [a, b) where the palms come closest, if within HANDOVER_M."""
    if b <= a:
        return None
    palms = palm_points(joints[a:b])
    d = np.linalg.norm(palms[:, 0] - palms[:, 1], axis=-1)
    k = int(np.argmin(d))
    return a + k if d[k] < HANDOVER_M else None


def _carry(track: np.ndarray, joints: np.ndarray, wrist_rot: np.ndarray, pick: Reach, put: Reach | None,
           grasp: np.ndarray) -> np.ndarray:
    """Fill ``track`` (T, 4, 4) rigid with the holding frame of ``pick``'s hands from its grasp frame
    to the release (``put.frame``, or the end; a one-hand put-down by the other hand takes over
    where the palms meet) and flag those hands in ``grasp`` (T, 2). Returns the held pose at the
    release frame (the last frame when never put down)."""
    r = put.frame if put is not None else len(track)
    pieces = [(pick.frame, r, pick.hands)]
    if put is not None and len(pick.hands) == 1 and len(put.hands) == 1 and put.hands != pick.hands:
        h = _handover(joints, pick.frame, r)
        if h is not None:
            pieces = [(pick.frame, h, pick.hands), (h, r, put.hands)]
    held = track[pick.frame].copy()
    for a, b, hands in pieces:
        H = holding_frames(joints[a:b + 1], wrist_rot[a:b + 1], hands)
        seg = H @ (inv_h(H[0]) @ held)
        track[a:b] = seg[: b - a]
        held = seg[-1]
        grasp[a:b, list(hands)] = True
    return held


def _carry_grip(joints: np.ndarray, a: int, b: int) -> float:
    """The palms' distance (m) of a two-hand carry on frames [a, b): its median. A box carried from
    the first frame is sized by it, not by the first frame's distance: the first frame of a clip is
    no grasp, and the palms may settle to another grip right after it (CMU 111_36: 25 cm on frame 0,
    31-38 cm over the 11 s of the carry; a box sized by frame 0 left both palms 5-7 cm off it)."""
    palms = palm_points(joints[a:max(b, a + 1)])
    return float(np.median(np.linalg.norm(palms[:, LEFT] - palms[:, RIGHT], axis=-1)))


def _spread_release(joints: np.ndarray, a: int, b: int, fps: float = 30.0) -> int | None:
    """First frame in (a, b) where the palms are RELEASE_SPREAD_M farther apart than they held the box,
    unless they then hold steadily (``_steady_carry``) at carry height: that is a new grip on the box,
    whose width the next release is measured from."""
    palms = palm_points(joints[a:b])
    d = np.linalg.norm(palms[:, 0] - palms[:, 1], axis=-1)
    low = palms[:, :, 2].min(axis=1)
    n = max(2, int(round(2 * RELEASE_HALF_S * fps)))  # frames after a spread that tell a re-grip
    ref, k = d[0], 1
    while True:
        far = np.flatnonzero(d[k:] > ref + RELEASE_SPREAD_M)
        if not len(far):
            return None
        f = k + int(far[0])
        if not _steady_carry(d[f:f + n], low[f:f + n], n):
            return a + f
        ref, k = float(np.median(d[f:f + n])), f + n


def _steady_carry(width: np.ndarray, low: np.ndarray, n: int) -> bool:
    """Palm distances (k,) and the lower palm's height (k,) m over the n frames after a spread: the
    palms stay steadily apart (std under STEADY_SPAN_M) and up (above CARRY_ABOVE_M on CARRY_SHARE
    of the frames) for all n frames (a clip that ends sooner decides nothing: a release)."""
    return len(width) >= n and float(np.std(width)) < STEADY_SPAN_M and float(np.mean(low > CARRY_ABOVE_M)) >= CARRY_SHARE


def fit_handled_objects(joints: np.ndarray, wrist_rot: np.ndarray, description: str,
                        seed: int = 0, fps: float = 30.0) -> HandledObjects:
    """Objects picked up / carried / put down in a clip (module doc). joints (T, 24, 3) m; wrist_rot
    (T, 2, 3, 3) global rotations of the left / right wrist; ``description`` the CMU text (a clip
    it does not hint at gets none). Object names are ``fit_<category>_<k>``. Deterministic in ``seed``."""
    j = np.asarray(joints, np.float64)
    T = len(j)
    if j.ndim != 3 or j.shape[1:] != (24, 3):
        raise ValueError(f"joints must be (T, 24, 3), got {j.shape}")
    if np.shape(wrist_rot) != (T, 2, 3, 3):
        raise ValueError(f"wrist_rot must be (T, 2, 3, 3) = ({T}, 2, 3, 3), got {np.shape(wrist_rot)}")
    out = HandledObjects(grasp=np.zeros((T, 2), bool))
    if not hinted(description):
        return out
    out.reaches = reaches = find_reaches(j)
    if not reaches and "carry" in description.lower():
        reaches = [r for r in [carried_from_start(j)] if r is not None]
    rng = np.random.default_rng([seed, 23])
    palms = palm_points(j)
    k = 0
    while k < len(reaches):
        pick = reaches[k]
        put = reaches[k + 1] if k + 1 < len(reaches) else None
        k += 2
        if len(pick.hands) == 2:  # two hands may let a box go without reaching down: they open
            f = _spread_release(j, pick.frame, put.frame if put is not None else T, fps)
            if f is not None:
                k -= put is not None  # the next reach down is not this put-down
                n = int(round(RELEASE_HALF_S * fps))
                put = Reach(max(f - n, pick.end), min(f + n, T), f, pick.hands)
        reach_xy = palms[pick.frame, list(pick.hands), :2].mean(axis=0)
        again = next((o for o in out.objects if o.meta.get("put_at") is not None
                      and np.linalg.norm(out.tracks[o.name][pick.frame, :2, 3] - reach_xy) < SAME_OBJECT_M), None)
        if again is None:
            kind = "box" if len(pick.hands) == 2 else "bottle"
            grip = _carry_grip(j, 0, put.frame if put is not None else T) if pick.in_hand else None
            obj, bottom = _new_object(f"fit_{kind}_{len(out.objects)}", j, pick, rng, grip)
            if not pick.in_hand:
                obj.pose, obj.meta["support"] = _stand(obj, obj.pose, bottom, out.supports, j, pick.frame)
            else:
                obj.pose[2, 3] = bottom  # in the hands at the first frame
            track = np.broadcast_to(obj.pose, (T, 4, 4)).copy()
            out.objects.append(obj)
        else:
            obj, track = again, out.tracks[again.name]
        out.tracks[obj.name] = track
        r = put.frame if put is not None else T
        held = _carry(track, j, wrist_rot, pick, put, out.grasp)
        out.intervals.append(ActionInterval("pick_up", pick.start, pick.end))
        if put is None:
            out.intervals.append(ActionInterval("carry", pick.end, T))
            obj.meta["put_at"] = None
            continue
        out.intervals += [ActionInterval("carry", pick.end, put.start), ActionInterval("put_down", put.start, put.end)]
        up, bottom = _upright(obj, held)
        rest, _ = _stand(obj, up, bottom, out.supports, j, r)
        centre = np.array([0.0, 0.0, obj.meta["size"][2] / 2, 1.0])
        out.release_jump_m.append(float(np.linalg.norm((rest @ centre - held @ centre)[:3])))
        track[r:] = rest
        obj.meta["put_at"] = int(r)
    for o in out.objects:
        o.pose = out.tracks[o.name][0].copy()
        o.meta.pop("put_at", None)
    out.intervals = [iv for iv in out.intervals if iv.end > iv.start]
    return out


def handled_footprints(handled: HandledObjects) -> list[np.ndarray]:
    """Floor quads (4, 2) m (axis-aligned bounds of the world mesh) of every object on every
    ``FOOTPRINT_EVERY``-th frame and the last: where it is carried or put (the placement keeps them free)."""
    out = []
    for o in handled.objects:
        track = handled.tracks[o.name]
        frames = np.unique(np.r_[np.arange(0, len(track), FOOTPRINT_EVERY), len(track) - 1])
        v = np.einsum("fij,vj->fvi", track[frames, :3, :3], o.mesh.vertices) + track[frames, None, :3, 3]
        lo, hi = v[..., :2].min(axis=1), v[..., :2].max(axis=1)  # (F, 2)
        out += [np.array([[a[0], a[1]], [b[0], a[1]], [b[0], b[1]], [a[0], b[1]]]) for a, b in zip(lo, hi)]
    return out
