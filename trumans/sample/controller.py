"""From a plan to per-episode controls: subgoals and frame-wise action labels (TRUMANS §4.1).

The plan is compiled once against the scene into *phases* (walk along an A* path, sit down, sit,
stand up, lie down, lie, get up, reach, act). The ``Controller`` then runs closed-loop: before each
episode it looks at where the body really is and returns the episode's control — the pelvis
subgoal at its last frame (``M_goal``) or a hand goal, and the action labels of its new frames
with the progress indicator. Walking subgoals lie on the path ``speed * (L - k) / fps`` metres
ahead of the body's projection onto the path (the training data's episode displacement), and
walking progress is the covered fraction of the path, so a body that lags still gets a reachable
goal. With the walk map, a subgoal whose straight line from the body's pelvis strays more than 5 cm
off the walkable floor is pulled back along the path until it does not (``line_of_sight_arc``): the
network walks roughly straight at its subgoal, so a subgoal past a corner made it cut the corner, into
the furniture the path turned around (the demo's right hip 6 cm into a table's corner). Timed
phases (sit down, stand up, ...) last their typical training-data duration. A phase done in place
(a turn, a timed action, a hand phase) starts with an episode, after the walk before it has run out
its episode (and up to ``max_approach`` more while the body is farther than ``arrive_m`` from the
walk's end): the data's walks end at rest, and a body still walking when a turn or a drink began
carried 0.3-0.7 m/s into it (the data: 0.0-0.15). A walk whose path leaves more than 35 degrees off
the body's heading starts with a turn on the spot (``compile_plan``), as every procedural take's walk
does; without it the network turned up to 180 degrees while walking, which the data never does, and
the walk windows were the farthest from the data's (docs/sampling_log.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trumans.scenes.walkability import NoPathError, WalkMap, nearest_walkable, plan_path

from trumans.sample.carry_plan import ObjectState, object_step_goals
from trumans.sample.plan import Plan
from trumans.sample.cleanup.reach import ReachCleanupConfig, reach_schedule, release_weights

__all__ = ["Phase", "EpisodeControl", "Controller", "compile_plan", "DEFAULT_SECONDS", "TURN_BEFORE_WALK", "free_margin", "seat_target",
           "lie_heading", "lie_head_flipped", "SYMMETRIC_LIE",
           "line_of_sight_arc", "off_walkable", "sit_down_subgoal"]

# a walk whose path leaves more than this off the body's heading starts with a turn on the spot
# (the procedural takes' threshold, ``trumans.synth.locomotion.walk``'s turn_threshold) where the
# spot lies this far (m) inside the walkable floor (``free_margin``; obstacles are another walk-map
# body radius, 0.25 m, away); in a tighter spot (a corner, against a wall) the body turns while it
# walks away: turning in place there swept elbows 9 cm into the eval rooms' furniture
TURN_BEFORE_WALK = np.radians(35.0)
TURN_FREE_MARGIN_M = 0.2
# typical durations (s) when the checkpoint carries none (meta "action_seconds")
DEFAULT_SECONDS: dict[str, float] = {
    "sit_down": 2.0, "stand_up": 1.8, "lie_down": 3.0, "get_up": 3.0, "reach": 1.5, "sit": 4.0, "lie": 4.0,
    "stand": 2.0, "turn": 1.1, "pick_up": 2.0, "put_down": 2.0, "open_door": 3.0, "close_door": 3.0, "open_drawer": 2.5,
    "close_drawer": 2.5, "drink": 3.0, "phone_call": 4.0, "type": 4.0, "use_mouse": 4.0,
}


@dataclass
class Phase:
    """One compiled phase. kind 'walk' follows ``path`` (P, 2) world xy m; the others last ``frames``
    frames with the pelvis subgoal ``goal`` (2,) (None = stay where the body is) or, for a reach,
    the hand goal ``hand_goal`` (3,) world m of joint ``hand``. ``actions``: labels switched on (the
    first gets the progress indicator; the others, e.g. a posture under a hand action, too)."""

    kind: str
    actions: tuple[str, ...]
    frames: int = 0
    path: np.ndarray | None = None
    goal: np.ndarray | None = None
    hand_goal: np.ndarray | None = None
    hand: str = "right_wrist"
    step: int = -1
    info: dict = field(default_factory=dict)
    guide: bool = True  # steer the body onto the goal (False: the goal is only inpainted, e.g. standing up)
    heading: float | None = None  # world heading (rad) at the goal: the seat's sitting direction; lying: lie_heading
    span: tuple[float, float] = (0.0, 1.0)  # progress indicator range of this phase (a part of one action)
    start: np.ndarray | None = None  # (2,) pelvis xy where the phase begins: mid-phase subgoals (sit_down_subgoal)

    @property
    def length(self) -> float:
        """Path length, m (walk phases)."""
        return float(np.linalg.norm(np.diff(self.path, axis=0), axis=1).sum()) if self.path is not None else 0.0


@dataclass
class EpisodeControl:
    """goal: (2,) pelvis xy at the episode's last frame, world m, or None; hand_goal: (3,) world m
    with ``hand`` and ``hand_frame`` (episode frame index) or None; labels: (L, N_A) float with the
    progress indicator for every frame of the episode (the transition frames keep their labels);
    phases: index of the active phase per episode frame (L,); reach_weight (L, 2) / reach_target
    (L, 2, 3) world m: the (left, right) wrist's reach cleanup weight and target per frame, from the
    hand phases (``trumans.sample.cleanup.reach``; 0 on the k transition frames)."""

    goal: np.ndarray | None
    labels: np.ndarray
    phases: np.ndarray
    hand_goal: np.ndarray | None = None
    hand: str = "right_wrist"
    hand_frame: int = -1
    guide: bool = True
    heading: float | None = None
    reach_weight: np.ndarray | None = None
    reach_target: np.ndarray | None = None


def _world(obj, local_xy) -> np.ndarray:
    """Object-frame point (2,) or (3,) -> world (same length)."""
    p = np.zeros(3)
    p[: len(local_xy)] = local_xy
    w = obj.pose[:3, :3] @ p + obj.pose[:3, 3]
    return w[: len(local_xy)]


def seat_target(obj, near: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(seat centre (3,) world m, seat height m) of a seat object (meta 'seat_center'); with
    ``near`` (world point), the place of meta 'seat_centers' (if any) nearest it in xy."""
    places = obj.meta.get("seat_centers") if near is not None else None
    local = [np.asarray(c, dtype=np.float64) for c in (places or [obj.meta["seat_center"]])]
    world = [_world(obj, c) for c in local]
    c = world[0] if near is None else min(world, key=lambda p: float(np.linalg.norm(p[:2] - np.asarray(near)[:2])))
    return c, float(c[2])


def _approach(obj, wm: WalkMap, seat: np.ndarray | None = None) -> np.ndarray:
    """Where to stand before sitting: meta 'approach', shifted with ``seat`` (world) from the seat
    centre to another seat place (as the procedural takes do)."""
    meta = obj.meta
    p = _world(obj, np.asarray(meta.get("approach", [0.0, 0.0]), dtype=np.float64))
    if seat is not None and "seat_center" in meta:
        p = p + (seat - _world(obj, np.asarray(meta["seat_center"], dtype=np.float64)))[: len(p)]
    return nearest_walkable(wm, p) if not wm.query(p[None])[0] else p


ANY_SIDE_SEATS = ("stool",)  # seats without a back: one can sit on them facing any side


def _sitting_side(obj, wm: WalkMap, seat: np.ndarray, free_at) -> tuple[np.ndarray, float]:
    """(where to stand before sitting (2,) world m, the sitting direction rad) for a seat: its meta
    'approach' and 'sit_yaw'; on a seat without a back (``ANY_SIDE_SEATS``) the side among the four
    (the approach turned about the seat by k x 90 deg) with the most room 0.65 m ahead of the seat
    (the walkable floor's free margin there, ``free_at``: m), so that standing up, which leans the
    trunk forward, does not put the head into a wall (the safety benchmark's stools faced walls
    0.7 m away); the meta side unless another has more than 10 cm more room."""
    yaw = float(np.arctan2(obj.pose[1, 0], obj.pose[0, 0]) + obj.meta.get("sit_yaw", 0.0))
    stand = _approach(obj, wm, seat=seat)
    if obj.category not in ANY_SIDE_SEATS:
        return stand, yaw
    meta = obj.meta
    raw = _world(obj, np.asarray(meta.get("approach", [0.0, 0.0]), dtype=np.float64))
    raw = raw + (seat - _world(obj, np.asarray(meta["seat_center"], dtype=np.float64)))[:2]
    ahead = raw - seat[:2]
    ahead = ahead / max(float(np.linalg.norm(ahead)), 1e-9)

    def room_ahead(k: int) -> float:  # the free margin where the head goes when standing up (0.65 m ahead)
        c, s = np.cos(k * np.pi / 2), np.sin(k * np.pi / 2)
        p = seat[:2] + 0.65 * (np.array([[c, -s], [s, c]]) @ ahead)
        return free_at(p) if wm.query(p[None])[0] else -1.0

    k = max((1, 2, 3), key=room_ahead)
    if room_ahead(k) <= room_ahead(0) + 0.1:
        return stand, yaw
    c, s = np.cos(k * np.pi / 2), np.sin(k * np.pi / 2)
    p = seat[:2] + np.array([[c, -s], [s, c]]) @ (raw - seat[:2])
    return (nearest_walkable(wm, p) if not wm.query(p[None])[0] else p), _wrap(yaw + k * np.pi / 2)


def _stand_facing(point: np.ndarray, pos: np.ndarray, wm: WalkMap) -> np.ndarray:
    """(2,) walkable floor point 0.45 m short of ``point`` (3,) on the way from ``pos`` (2,)."""
    d = point[:2] - pos
    stand = point[:2] - 0.45 * d / max(np.linalg.norm(d), 1e-6)
    return nearest_walkable(wm, stand) if not wm.query(stand[None])[0] else stand


def lie_heading(obj, flip: bool = False) -> float | None:
    """The body heading (rad, world; ``trumans.skeleton.heading``: perpendicular to the hip line) of a person
    lying on their back on ``obj`` with the head along its ``lie_yaw`` (meta, local frame: the feet -> head
    direction; a bed's headboard end, ``trumans.scenes.furniture`` / ``affordances``): the hip line's forward
    points to the feet, so heading = object yaw + lie_yaw + pi; ``flip``: the head at the other end
    (``lie_head_flipped``). None when the object gives no ``lie_yaw``."""
    if "lie_yaw" not in obj.meta:
        return None
    return _wrap(float(np.arctan2(obj.pose[1, 0], obj.pose[0, 0])) + float(obj.meta["lie_yaw"]) + np.pi
                 + (np.pi if flip else 0.0))


SYMMETRIC_LIE = ("sofa",)  # lying objects whose two ends are alike (no headboard, no pillow): the head may go to either
# where a lying object's end's room is taken: this far (m) inside the lying length from the end, and this far
# beyond the approach point (0.2 m in front of a sofa: too close to be walkable) in front of the object
LIE_END_INSIDE_M, LIE_END_AHEAD_M = 0.1, 0.35


def lie_head_flipped(obj, wm: WalkMap, free_at) -> bool:
    """Whether a person lying on ``obj`` should put the head at the end opposite its ``lie_yaw``: only for
    ``SYMMETRIC_LIE`` objects, when the floor in front of the other end has more than 10 cm more room (the
    walkable floor's free margin, ``free_at``: m; -1 off the floor) ``LIE_END_AHEAD_M`` beyond the approach
    point and ``LIE_END_INSIDE_M`` inside the lying length (meta 'lie_length') from the end. The network lays
    the body down from the edge seat and its head can swing in front of the cushion: at a sofa's end with a
    cabinet in front of it the head went into the cabinet's drawer (the safety benchmark's plan 13, 7.7 cm;
    the drawer front is thinner than the field's voxels, so no cleanup step sees it)."""
    meta = obj.meta
    if obj.category not in SYMMETRIC_LIE or not all(k in meta for k in ("lie_yaw", "lie_center", "approach")):
        return False
    half = 0.5 * float(meta.get("lie_length", 1.8)) - LIE_END_INSIDE_M
    c, a = np.asarray(meta["lie_center"], dtype=np.float64)[:2], np.asarray(meta["approach"], dtype=np.float64)[:2]
    head = np.array([np.cos(float(meta["lie_yaw"])), np.sin(float(meta["lie_yaw"]))])
    ahead = (a - c) - ((a - c) @ head) * head  # from the lying centre to the approach, across the lying direction
    ahead = ahead * (1.0 + LIE_END_AHEAD_M / max(float(np.linalg.norm(ahead)), 1e-9))

    def room(sign: float) -> float:
        q = _world(obj, c + ahead + sign * half * head)
        return free_at(q) if wm.query(q[None])[0] else -1.0

    return room(-1.0) > room(1.0) + 0.1


def compile_plan(plan: Plan, scene, wm: WalkMap, start_xy: np.ndarray, seconds: dict[str, float],
                 fps: float, spacing: float = 0.3, vocabulary: tuple[str, ...] | list[str] = (),
                 heading: float | None = None) -> list[Phase]:
    """Phases of ``plan`` in ``scene`` from ``start_xy`` (2,) facing ``heading`` (rad; None =
    unknown). Raises ValueError (naming the step) when a goal is not reachable on the walkable
    floor. The phases follow the training data's order, as far as the model's ``vocabulary`` has
    the actions: a walk whose path leaves more than ``TURN_BEFORE_WALK`` off the body's heading
    starts with a turn on the spot to the path's direction (the procedural takes' rule,
    ``trumans.synth.locomotion``; the heading is followed through the plan: a walk ends facing along
    its path, a seated body faces the seat's sitting direction, unknown after lying or a reach);
    sitting down starts with a turn on the spot to the seat's sitting direction (the procedural
    takes turn ~150 degrees, then sit down without turning); lying down first sits on the edge at
    the seat place nearest the lying pelvis, and getting up ends seated there, then stands up."""
    def frames(name: str, s: float | None = None) -> int:
        return max(2, int(round((s if s is not None else seconds.get(name, DEFAULT_SECONDS.get(name, 2.0))) * fps)))

    phases: list[Phase] = []
    pos = np.asarray(start_xy, dtype=np.float64)
    yaw_now = None if heading is None else float(heading)  # where the body faces (rad), None = unknown
    free: list[np.ndarray] = []  # free_margin(wm), computed at the first walk that may turn

    def _free_at(p: np.ndarray) -> float:
        if not free:
            free.append(free_margin(wm))
        i = np.clip(wm.index(p), 0, np.asarray(wm.walkable.shape) - 1)
        return float(free[0][i[0], i[1]])
    if not wm.query(pos[None])[0]:  # a body slightly off the walkable floor plans from the nearest free cell
        pos = nearest_walkable(wm, pos)
    posture: str | None = None  # "sit" / "lie" while seated / lying
    posture_exit: np.ndarray | None = None
    objects = ObjectState()  # where moved objects are, what the hands hold

    edge_seat: np.ndarray | None = None  # where a lying body sat down on the edge (and gets up to)

    def leave(i: int) -> None:
        nonlocal posture, pos
        if posture == "sit":
            phases.append(Phase("stand_up", ("stand_up",), frames("stand_up"), goal=posture_exit, step=i, guide=False))
        elif posture == "lie":
            phases.append(Phase("get_up", ("get_up",), frames("get_up"), step=i, guide=False,
                                goal=posture_exit if edge_seat is None else edge_seat))
            if edge_seat is not None:  # the data's get_up ends seated on the edge: then stand up
                phases.append(Phase("stand_up", ("stand_up",), frames("stand_up"), goal=posture_exit, step=i,
                                    guide=False))
        if posture is not None:
            pos = posture_exit
        posture = None

    def walk(i: int, goal: np.ndarray) -> None:
        nonlocal pos, yaw_now
        leave(i)
        if not wm.query(goal[None])[0]:
            raise ValueError(f"plan step {i + 1}: goal {np.round(goal, 2).tolist()} is not on walkable floor "
                             f"(inside furniture, a wall or outside the room); choose another point")
        if np.linalg.norm(goal - pos) < 0.15:
            return
        try:
            path = plan_path(wm, pos, goal, spacing=spacing)
        except NoPathError as e:
            raise ValueError(f"plan step {i + 1}: no walkable path from {np.round(pos, 2).tolist()} to "
                             f"{np.round(goal, 2).tolist()} ({e})") from None
        out_dir, in_dir = _path_direction(path, 0), _path_direction(path, -1)
        if yaw_now is not None and "turn" in vocabulary and abs(_wrap(out_dir - yaw_now)) > TURN_BEFORE_WALK \
                and _free_at(pos) >= TURN_FREE_MARGIN_M:
            phases.append(Phase("turn", ("turn",), frames("turn"), goal=pos.copy(), step=i, heading=out_dir))
        phases.append(Phase("walk", ("walk",), path=path, goal=goal, step=i))
        pos, yaw_now = goal, in_dir

    for i, s in enumerate(plan.steps):
        obj = scene.objects.get(s.object) if s.object else None
        if s.kind == "goto":
            walk(i, np.asarray(s.to, dtype=np.float64))
        elif s.kind in ("sit_on", "lie_on"):
            lie = _world(obj, np.asarray(obj.meta["lie_center"], dtype=np.float64)) if s.kind == "lie_on" else None
            flip = s.kind == "lie_on" and lie_head_flipped(obj, wm, _free_at)  # the head at the end with room
            # lying as in the data: sit on the edge first (the seat place nearest the lying pelvis; flipped, of two
            # places as near, the one at the head's end, which has the room: not the feet in front of the cabinet)
            via_edge = lie is not None and "seat_center" in obj.meta and "sit_down" in vocabulary
            if s.kind == "sit_on" or via_edge:
                near = lie
                if flip:
                    yaw_w = float(np.arctan2(obj.pose[1, 0], obj.pose[0, 0]) + obj.meta["lie_yaw"]) + np.pi
                    near = lie + 1e-3 * np.array([np.cos(yaw_w), np.sin(yaw_w), 0.0])
                seat, h = seat_target(obj, near=near)
                stand, yaw = _sitting_side(obj, wm, seat, _free_at)
                walk(i, stand)
                if "turn" in vocabulary:
                    phases.append(Phase("turn", ("turn",), frames("turn"), goal=pos.copy(),
                                        step=i, heading=yaw, info={"object": obj.name}))
                phases.append(Phase("sit_down", ("sit_down",), frames("sit_down"), goal=seat[:2], step=i,
                                    info={"seat_height": h, "object": obj.name}, heading=yaw, start=pos.copy()))
                yaw_now = yaw if s.kind == "sit_on" else None
            else:
                walk(i, _approach(obj, wm))
                yaw_now = None
            if s.kind == "sit_on":
                phases.append(Phase("sit", ("sit",), frames("sit", s.seconds), goal=seat[:2], step=i,
                                    info={"seat_height": h, "object": obj.name}, heading=yaw))
                posture = "sit"
                edge_seat = None
            else:
                phases.append(Phase("lie_down", ("lie_down",), frames("lie_down"), goal=lie[:2], step=i,
                                    info={"surface_height": float(lie[2]), "object": obj.name},
                                    heading=lie_heading(obj, flip)))
                phases.append(Phase("lie", ("lie",), frames("lie", s.seconds), goal=lie[:2], step=i,
                                    info={"surface_height": float(lie[2]), "object": obj.name},
                                    heading=lie_heading(obj, flip)))
                posture = "lie"
                edge_seat = seat[:2].copy() if via_edge else None
            posture_exit = pos.copy()
        elif s.kind in ("stand_up", "get_up"):
            if posture is None:
                raise ValueError(f"plan step {i + 1}: {s.kind} but the person is not seated or lying")
            leave(i)
        elif s.kind == "act":
            held = ("sit",) if posture == "sit" else ("lie",) if posture == "lie" else ()
            phases.append(Phase("act", (s.action, *held), frames(s.action, s.seconds), goal=None, step=i))
        elif s.kind in ("pick_up", "put_down", "open", "close"):  # object steps: trumans.sample.carry_plan
            sg = object_step_goals(scene, s, objects, pos)
            stand = sg.stand if wm.query(sg.stand[None])[0] else nearest_walkable(wm, sg.stand)
            walk(i, stand)
            action = s.kind if s.kind in ("pick_up", "put_down") else f"{s.kind}_{scene.objects[s.object].category}"
            hand = "left_wrist" if s.hand == "left" else "right_wrist"
            for part, (point, span) in enumerate(zip(sg.points, sg.spans)):
                info = {"object": s.object, "do": s.kind, "part": part}
                if part == 1 and sg.path is not None:  # the moving part: the hand follows the handle (reach cleanup)
                    info["hand_path"] = sg.path
                phases.append(Phase("reach", (action,), max(2, int(round((span[1] - span[0]) * frames(action)))),
                                    hand_goal=point, hand=hand, step=i, span=span, info=info))
            phases[-1].info["after"] = sg.after  # where the object is once the step is done (scene grids)
            yaw_now = None
        elif s.kind == "reach":
            target = s.target
            if isinstance(target, str):
                tobj = scene.objects[target]
                meta = tobj.meta
                local = meta.get("grasp_point") or meta.get("handle") or meta.get("surface_center") or [0, 0, 0]
                point = tobj.pose[:3, :3] @ np.asarray(local, dtype=np.float64) + tobj.pose[:3, 3]
                support = scene.objects.get(meta.get("support", ""), tobj)
                stand = _approach(support if "approach" in support.meta else tobj, wm)
            else:
                point = np.asarray(target, dtype=np.float64)
                stand = _stand_facing(point, pos, wm)
            walk(i, stand)
            action = "reach"
            hand = "left_wrist" if s.hand == "left" else "right_wrist"
            phases.append(Phase("reach", (action,), frames(action), hand_goal=point, hand=hand, step=i,
                                info={"object": target if isinstance(target, str) else None}))
            yaw_now = None
    return phases


def free_margin(wm: WalkMap) -> np.ndarray:
    """(Nx, Ny) m: how far each walk-map cell centre is inside the walkable floor (the distance to the
    nearest cell that is not walkable; 0 off it). The walk map already keeps its body radius off
    obstacles, so an obstacle is this plus that radius away."""
    from scipy import ndimage

    return ndimage.distance_transform_edt(wm.walkable) * wm.cell


def _wrap(a: float) -> float:
    """Angle (rad) wrapped to [-pi, pi)."""
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def _path_direction(path: np.ndarray, end: int, look_m: float = 0.3) -> float:
    """World heading (rad) of a path (P, 2) leaving its start (``end`` 0) or arriving at its end
    (``end`` -1): the direction to / from the path point ``look_m`` m along it."""
    pts = path if end == 0 else path[::-1]
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    q = np.array([np.interp(min(look_m, cum[-1]), cum, pts[:, 0]), np.interp(min(look_m, cum[-1]), cum, pts[:, 1])])
    d = q - pts[0] if end == 0 else pts[0] - q
    return float(np.arctan2(d[1], d[0]))


def sit_down_subgoal(start: np.ndarray, goal: np.ndarray, progress: float) -> np.ndarray:
    """Pelvis xy (2,) world m at ``progress`` in [0, 1] of a phase that moves it from ``start`` to
    ``goal``: smooth step 3p² - 2p³, the data's sit-down profile (distance to the seat 0.35 → 0.26 →
    0.10 → 0.04 m at 0, 0.5, 1, 1.5 s of a 1.6 s sit-down, the dataset's test and val takes). The
    seat as the subgoal of an episode that ends halfway through made the body reach it ~0.5 s early."""
    p = float(np.clip(progress, 0.0, 1.0))
    return np.asarray(start, np.float64) + (3 * p ** 2 - 2 * p ** 3) * (np.asarray(goal, np.float64) - start)


def off_walkable(wm: WalkMap) -> np.ndarray:
    """(Nx, Ny) m: how far each walk-map cell centre is from the nearest walkable one (0 on walkable floor)."""
    from scipy import ndimage

    if not wm.walkable.any():
        return np.full(wm.walkable.shape, np.inf)
    return ndimage.distance_transform_edt(~wm.walkable) * wm.cell


def line_of_sight_arc(wm: WalkMap, off: np.ndarray, path: np.ndarray, cum: np.ndarray, s0: float, s1: float,
                      start: np.ndarray, slack: float = 0.05, step: float = 0.05) -> float:
    """The largest arc length s in (s0, s1] (m along ``path`` (P, 2) world xy, ``cum`` (P,) its
    cumulative arc length) whose path point is seen from ``start`` (2,) world xy (the body's pelvis):
    the straight line between them (sampled every half walk-map cell) stays within ``slack`` m of
    walkable floor (``off``: ``off_walkable(wm)``); candidates every ``step`` m back from ``s1``.
    A pelvis off the floor's margin (pressed to a wall's end or furniture) looks from the nearest
    walkable cell; if still none is seen, the nearest candidate (never a point across a wall: the
    safety benchmark's partition plan aimed 1 m ahead through the wall from the wall's end and stood
    there to the end of its time, docs/results.md "Scene safety")."""
    cand = np.concatenate([[s1], np.arange(s1 - step, s0, -step)])  # (C,) from the farthest back
    pts = lambda s: np.stack([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])], -1)  # noqa: E731
    a, b = np.asarray(start, np.float64), pts(cand)  # (2,), (C, 2)
    ia = wm.index(a)
    if not (np.all((ia >= 0) & (ia < np.asarray(off.shape))) and off[ia[0], ia[1]] <= slack + 1e-9):
        a = nearest_walkable(wm, a)
    n = max(2, int(np.ceil(np.linalg.norm(b - a, axis=-1).max() / (0.5 * wm.cell))) + 1)
    idx = wm.index(a + np.linspace(0.0, 1.0, n)[None, :, None] * (b[:, None] - a))  # (C, n, 2)
    inside = np.all((idx >= 0) & (idx < np.asarray(off.shape)), axis=-1)
    c = np.clip(idx, 0, np.asarray(off.shape) - 1)
    seen = (inside & (off[c[..., 0], c[..., 1]] <= slack + 1e-9)).all(-1)  # (C,)
    return float(cand[np.argmax(seen)]) if seen.any() else float(cand[-1])


class Controller:
    """Closed-loop episode controls for compiled ``phases``; see the module doc.

    vocabulary: the model's action names; L, k: episode and transition frames; speed: walking
    speed, m/s; fps: the model's frame rate; reach: the reach cleanup's config, whose ramps schedule
    the reach weights of the hand phases (the rollout passes ``SamplerConfig.cleanup.reach``);
    walkmap: the plan's walk map (None: subgoals are not kept in line of sight)."""

    def __init__(self, phases: list[Phase], vocabulary: list[str], L: int, k: int, fps: float,
                 speed: float = 1.0, arrive_m: float = 0.25, reach: ReachCleanupConfig = ReachCleanupConfig(),
                 walkmap: WalkMap | None = None) -> None:
        if not phases:
            raise ValueError("the plan compiled to no phases (every goal is where the person already stands)")
        self.phases, self.vocab = phases, list(vocabulary)
        self.col = {a: i for i, a in enumerate(self.vocab)}
        self.L, self.k, self.fps, self.speed, self.arrive = L, k, fps, float(speed), float(arrive_m)
        self.index = 0  # current phase
        self.elapsed = 0  # frames spent in the current phase
        self.walk_s = 0.0  # arc length planned on the current walk path, m
        self.body_s = 0.0  # arc length the body has covered (its projection on the path), m
        self._cum: np.ndarray | None = None
        self.approach_tries = 0  # extra episodes spent walking onto the end of a walk before an in-place phase
        self.max_approach = 4
        self.reach = reach
        self.walkmap = walkmap
        self._off = off_walkable(walkmap) if walkmap is not None else None
        # contacts whose release still fades out: (last contact frame relative to the next episode's
        # frames, wrist target (3,), side 0 left / 1 right)
        self.releases: list[tuple[int, np.ndarray, int]] = []

    def _release(self, weight: np.ndarray, target: np.ndarray, events: list[tuple[int, np.ndarray, int]]) -> None:
        """Fade out the contacts that ended (``events`` and the carried-over ``releases``) into the
        reach ``weight`` (L, 2) / ``target`` (L, 2, 3) of the new frames; keep those still fading."""
        L, k = len(weight), self.k
        keep = []
        for e, point, side in self.releases + events:
            t = np.arange(max(e + 1, k), L)
            w_out = release_weights(t - e, self.fps, self.reach)
            w_in, t_in = weight[t, side], target[t, side]
            total = np.maximum(w_in + w_out, 1e-12)[:, None]
            target[t, side] = np.where((w_out > 0)[:, None], (w_in[:, None] * t_in + w_out[:, None] * point) / total,
                                       t_in)
            weight[t, side] = np.maximum(w_in, w_out)
            if release_weights(np.array([L - e]), self.fps, self.reach)[0] > 0:  # next episode's first new frame
                keep.append((e - (L - k), point, side))
        self.releases = keep

    @property
    def done(self) -> bool:
        return self.index >= len(self.phases)

    def _arc(self, path: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])

    def _point_at(self, path: np.ndarray, cum: np.ndarray, s: float) -> np.ndarray:
        s = float(np.clip(s, 0.0, cum[-1]))
        return np.array([np.interp(s, cum, path[:, 0]), np.interp(s, cum, path[:, 1])])

    def _project(self, path: np.ndarray, cum: np.ndarray, p: np.ndarray) -> float:
        """Arc length of the closest path point to p (2,)."""
        a, b = path[:-1], path[1:]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
        q = a + t[:, None] * ab
        i = int(np.argmin(np.linalg.norm(q - p, axis=1)))
        return float(cum[i] + t[i] * np.linalg.norm(ab[i]))

    @staticmethod
    def _in_place(p: Phase | None) -> bool:
        """A phase done where the walk before it ends: a hand phase, a turn, a timed action."""
        return p is not None and (p.hand_goal is not None or p.kind in ("turn", "act"))

    def _approach_goal(self, p: Phase | None, pelvis_xy: np.ndarray) -> np.ndarray | None:
        """The walk's end (2,) before an in-place phase that is about to start while the pelvis is
        farther than ``arrive_m`` from it (at most ``max_approach`` extra walking episodes), else None."""
        if p is None or not self._in_place(p) or self.elapsed > 0 or self.index == 0:
            self.approach_tries = 0 if p is None or self.elapsed > 0 else self.approach_tries
            return None
        prev = self.phases[self.index - 1]
        if prev.kind != "walk" or self.approach_tries >= self.max_approach or "walk" not in self.col or \
                np.linalg.norm(np.asarray(prev.goal) - pelvis_xy) <= self.arrive:
            return None
        self.approach_tries += 1
        return np.asarray(prev.goal, np.float64)

    def next(self, pelvis_xy: np.ndarray, prev_labels: np.ndarray) -> EpisodeControl:
        """Control of the next episode given the body's pelvis xy (2,) at its first new frame
        and the labels of the k transition frames (k, N_A)."""
        L, k = self.L, self.k
        labels = np.zeros((L, len(self.vocab)), np.float32)
        labels[:k] = prev_labels
        phase_of = np.full(L, -1, np.int64)
        step_m = self.speed / self.fps
        goal = hand_goal = None
        hand, hand_frame, guide, heading = "right_wrist", -1, True, None
        reach_w, reach_t, events = np.zeros((L, 2)), np.zeros((L, 2, 3)), []
        f = k
        p = self.phases[self.index] if not self.done else None
        approach = self._approach_goal(p, pelvis_xy)
        if approach is not None:  # the body lags behind its path: finish walking before the in-place phase
            labels[k:, self.col["walk"]] = 2.0
            phase_of[k:] = self.index - 1
            self._release(reach_w, reach_t, [])
            return EpisodeControl(approach, labels, phase_of, reach_weight=reach_w, reach_target=reach_t)
        if p is not None and p.kind == "walk":  # anchor on the path where the body really is (closed loop)
            cum = self._arc(p.path)
            self.walk_s = max(self.body_s, self._project(p.path, cum, np.asarray(pelvis_xy, np.float64)))
            self.body_s = self.walk_s
        while f < L and not self.done:
            p = self.phases[self.index]
            if p.kind == "walk":
                cum = self._arc(p.path)
                remaining = cum[-1] - self.walk_s
                n = max(1, min(L - f, int(np.ceil(remaining / step_m))))
                s = self.walk_s + step_m * np.arange(1, n + 1)
                if self.walkmap is not None and f + n >= L and s[-1] < cum[-1]:  # the walk goes on: no corner cut
                    seen = line_of_sight_arc(self.walkmap, self._off, p.path, cum, self.walk_s, s[-1],
                                             np.asarray(pelvis_xy, np.float64))
                    s = np.minimum(s, seen)
                prog = np.clip(s / max(cum[-1], 1e-6), 0, 1)
                labels[f:f + n, self.col["walk"]] = 1.0 + prog
                phase_of[f:f + n] = self.index
                goal, guide, heading = self._point_at(p.path, cum, s[-1]), True, None
                self.walk_s = float(min(s[-1], cum[-1]))
                f += n
                if self.walk_s >= cum[-1] - 1e-6:
                    if self.index + 1 < len(self.phases) and self._in_place(self.phases[self.index + 1]):
                        labels[f:, self.col["walk"]] = 2.0  # an in-place phase starts with an episode (_approach_goal)
                        phase_of[f:] = self.index
                        f = L
                    self.index, self.elapsed, self.walk_s, self.body_s = self.index + 1, 0, 0.0, 0.0
            else:
                n = min(L - f, p.frames - self.elapsed)
                prog = p.span[0] + (p.span[1] - p.span[0]) * (self.elapsed + np.arange(1, n + 1)) / p.frames
                for j, a in enumerate(p.actions):
                    if a in self.col:
                        labels[f:f + n, self.col[a]] = 1.0 + (prog if j == 0 else 0.5)
                phase_of[f:f + n] = self.index
                if p.hand_goal is not None:
                    hand_goal, hand, hand_frame, goal = p.hand_goal, p.hand, f + n - 1, None
                    side = 0 if p.hand.startswith("left") else 1
                    reach_w[f:f + n, side], reach_t[f:f + n, side] = reach_schedule(
                        p, self.elapsed + np.arange(n), self.fps, self.reach)
                    nxt = self.phases[self.index + 1] if self.index + 1 < len(self.phases) else None
                    held = nxt is not None and nxt.step == p.step and nxt.hand_goal is not None  # open / close goes on
                    if self.elapsed + n >= p.frames and not held:
                        events.append((f + n - 1, reach_t[f + n - 1, side].copy(), side))
                elif p.goal is not None:
                    goal = np.asarray(p.goal, np.float64)
                    if p.start is not None and self.elapsed + n < p.frames:  # the episode ends inside the phase
                        goal = sit_down_subgoal(p.start, goal, (self.elapsed + n) / p.frames)
                guide, heading = p.guide, p.heading
                self.elapsed += n
                f += n
                if self.elapsed >= p.frames:
                    self.index, self.elapsed = self.index + 1, 0
        if f < L:  # the plan is over: stand (or hold the posture) where the body is
            last = phase_of[f - 1] if f > 0 and phase_of[f - 1] >= 0 else None
            held = self.phases[last].actions[-1] if last is not None and self.phases[last].kind in ("sit", "lie", "sit_down", "lie_down") else "stand"
            held = {"sit_down": "sit", "lie_down": "lie"}.get(held, held)
            if held in self.col:
                labels[f:, self.col[held]] = 1.5
            if goal is None and hand_goal is None:
                goal = np.asarray(pelvis_xy, np.float64)
        if goal is None and hand_goal is None:
            goal = np.asarray(pelvis_xy, np.float64)
        self._release(reach_w, reach_t, events)
        return EpisodeControl(goal, labels, phase_of, hand_goal, hand, hand_frame, guide, heading, reach_w, reach_t)
