"""Procedural rooms: floor, four walls with a door, furniture placed by rejection sampling.

Room frame (world): the interior is x in [0, W], y in [0, D] (W, D in 4-7 m unless given), floor
top at z = 0, walls 2.6 m high and ``WALL_THICKNESS`` thick outside the interior. Furniture
meshes and meta follow the contract in :mod:`trumans.scenes.furniture` (local frames, +x = front).

Placement: each floor piece (or group: a desk with its chair) is an oriented footprint rectangle;
a candidate pose is accepted when (1) its footprint is inside the room, (2) its footprint grown
by ``MARGIN`` overlaps no placed footprint, (3) its clear zone (a square of half-size
``ZONE_HALF`` around its approach point, stretched to its footprint) lies inside the room and
overlaps no footprint and no placed footprint enters it, and (4) on a ``CELL`` grid whose cells
within ``BODY_RADIUS`` of a footprint or wall are blocked, every approach point placed so far is
4-connected to the door's approach point (flood fill by ``scipy.ndimage.label``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import ndimage

from trumans.scenes import furniture as F
from trumans.scenes.scene import Scene, SceneObject

__all__ = [
    "make_room",
    "list_categories",
    "floor_footprints",
    "approach_points",
    "reachable_approaches",
    "quads_overlap",
    "WALL_HEIGHT",
    "WALL_THICKNESS",
]

WALL_HEIGHT = 2.6  # m
WALL_THICKNESS = 0.12  # m
ROOM_RANGE = (4.0, 7.0)  # m, side length of random rooms
MARGIN = 0.08  # m, clearance between footprints
ZONE_HALF = 0.30  # m, half-size of the free square around an approach point
BODY_RADIUS = 0.12  # m, obstacle growth for the walkability flood fill
CELL = 0.05  # m, walkability grid cell
ATTEMPTS = 120  # candidate poses per piece
GAP = F.GAP

# placement order (large first) and mode: 'wall' = back (-x) against a wall, facing the room
_ORDER = {"desk": 0, "table": 1, "bed": 2, "sofa": 3, "cabinet": 4, "chair": 5, "stool": 6}
_SURFACES = ("table", "desk", "cabinet")


def list_categories() -> list[str]:
    """Every object category make_room can produce (floor pieces, attached and small objects)."""
    return sorted(set(F.FLOOR_CATEGORIES) | set(F.SMALL_CATEGORIES) | set(F.DESK_ITEM_CATEGORIES)
                  | {"drawer", "door"})


# ----------------------------------------------------------------------------- 2D geometry


def _rect_quad(lo: np.ndarray, hi: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(4, 2) world corners of the local rectangle [lo, hi] (2,) under the (4, 4) pose T."""
    c = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    return c @ T[:2, :2].T + T[:2, 3]


def quads_overlap(a: np.ndarray, b: np.ndarray, eps: float = 1e-9) -> bool:
    """Separating-axis test for two convex quads (4, 2); touching counts as no overlap."""
    for q in (a, b):
        e = np.roll(q, -1, axis=0) - q
        nrm = np.stack([-e[:, 1], e[:, 0]], axis=1)  # (4, 2) edge normals
        pa, pb = a @ nrm.T, b @ nrm.T  # (4, 4) projections
        if np.any((pa.max(0) <= pb.min(0) + eps) | (pb.max(0) <= pa.min(0) + eps)):
            return False
    return True


def _inside(q: np.ndarray, W: float, D: float, tol: float = 1e-9) -> bool:
    return bool(np.all(q >= -tol) and np.all(q[:, 0] <= W + tol) and np.all(q[:, 1] <= D + tol))


def _local_rect(obj: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    b = obj.mesh.bounds
    return b[0, :2].copy(), b[1, :2].copy()


@dataclass
class _Footprint:
    """An exact floor footprint: local rectangle [lo, hi] of an object under its world pose."""

    name: str
    pose: np.ndarray  # (4, 4)
    lo: np.ndarray  # (2,)
    hi: np.ndarray  # (2,)

    def quad(self, grow: float = 0.0) -> np.ndarray:
        return _rect_quad(self.lo - grow, self.hi + grow, self.pose)


@dataclass
class _Placed:
    quad: np.ndarray  # (4, 2) group footprint
    zone: np.ndarray | None  # (4, 2) clear zone


class _Walkable:
    """Coarse free-space grid of the room interior (True = free) updated as pieces are placed."""

    def __init__(self, W: float, D: float) -> None:
        nx, ny = int(np.ceil(W / CELL)), int(np.ceil(D / CELL))
        xs, ys = (np.arange(nx) + 0.5) * CELL, (np.arange(ny) + 0.5) * CELL
        self.W, self.D = W, D
        self.xy = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)  # (nx, ny, 2)
        x, y = self.xy[..., 0], self.xy[..., 1]
        r = BODY_RADIUS
        self.free = (x > r) & (x < W - r) & (y > r) & (y < D - r)

    def blocked_by(self, fps: list[_Footprint]) -> np.ndarray:
        """(nx, ny) bool: cells within BODY_RADIUS (box-grown) of any footprint."""
        out = np.zeros(self.free.shape, dtype=bool)
        for fp in fps:
            R, t = fp.pose[:2, :2], fp.pose[:2, 3]
            loc = (self.xy - t) @ R  # world -> local: R^T (p - t)
            out |= np.all((loc >= fp.lo - BODY_RADIUS) & (loc <= fp.hi + BODY_RADIUS), axis=-1)
        return out

    def cell(self, p: np.ndarray) -> tuple[int, int]:
        i = int(np.clip(p[0] // CELL, 0, self.free.shape[0] - 1))
        j = int(np.clip(p[1] // CELL, 0, self.free.shape[1] - 1))
        return i, j

    def connected(self, free: np.ndarray, source: np.ndarray, targets: list[np.ndarray]) -> bool:
        """Whether every target (2,) world point is 4-connected to ``source`` through free cells."""
        lab, _ = ndimage.label(free)
        s = lab[self.cell(source)]
        return bool(s > 0 and all(lab[self.cell(p)] == s for p in targets))


# ----------------------------------------------------------------------------- walls and door

# wall k: inner-face point p(t), inward normal n, yaw of an object facing the room, length axis
_WALL_NORMALS = {0: (0.0, 1.0), 1: (-1.0, 0.0), 2: (0.0, -1.0), 3: (1.0, 0.0)}


def _wall_point(k: int, t: float, W: float, D: float) -> np.ndarray:
    return np.array([(t, 0.0), (W, t), (t, D), (0.0, t)][k])


def _wall_length(k: int, W: float, D: float) -> float:
    return W if k in (0, 2) else D


def _wall_mesh(k: int, W: float, D: float, opening: tuple[float, float, float] | None) -> trimesh.Trimesh:
    """Wall k as disjoint boxes; ``opening`` = (t0, t1, height) along the wall's axis (x or y)."""
    T, H = WALL_THICKNESS, WALL_HEIGHT
    if k in (0, 2):
        a0, a1 = -T, W + T
        c0, c1 = (-T, 0.0) if k == 0 else (D, D + T)
    else:
        a0, a1 = GAP, D - GAP
        c0, c1 = (W, W + T) if k == 1 else (-T, 0.0)
    spans = [(a0, a1, 0.0, H)]
    if opening is not None:
        t0, t1, oh = opening
        spans = [(a0, t0, 0.0, H), (t1, a1, 0.0, H), (t0 + GAP, t1 - GAP, oh, H)]
    parts = []
    for s0, s1, z0, z1 in spans:
        if k in (0, 2):
            parts.append(F._box((s0, c0, z0), (s1, c1, z1)))
        else:
            parts.append(F._box((c0, s0, z0), (c1, s1, z1)))
    return F._assemble(parts)


# ----------------------------------------------------------------------------- planning


def _plan(rng: np.random.Generator, furniture: list[str] | None) -> tuple[list[str], list[str], bool]:
    """(floor categories in placement order, small categories, explicit?) for a room."""
    if furniture is not None:
        allowed = set(F.FLOOR_CATEGORIES) | set(F.SMALL_CATEGORIES)
        bad = [c for c in furniture if c not in allowed]
        if bad:
            raise ValueError(f"furniture: unknown or non-placeable categories {bad}; choose from "
                             f"{sorted(allowed)} (keyboard/mouse/laptop come with a desk, drawers with a "
                             f"cabinet, the door with every room)")
        floor = [c for c in furniture if c in F.FLOOR_CATEGORIES]
        small = [c for c in furniture if c in F.SMALL_CATEGORIES]
        if small and not any(c in _SURFACES for c in floor):
            raise ValueError(f"furniture: small objects {small} need a surface; add 'table', 'desk' or 'cabinet'")
        return sorted(floor, key=lambda c: _ORDER[c]), small, True
    floor = ["desk" if rng.random() < 0.5 else "table"]
    big = str(rng.choice(["bed", "sofa", "none"], p=[0.45, 0.30, 0.25]))
    if big != "none":
        floor.append(big)
    if rng.random() < 0.65:
        floor.append("cabinet")
    n_seats = int(rng.integers(1, 3))
    kinds = [str(k) for k in rng.permutation(["chair", "stool", "sofa"]) if not (k == "sofa" and big == "sofa")]
    floor += kinds[:n_seats]
    small = [str(c) for c in rng.choice(F.SMALL_CATEGORIES, size=int(rng.integers(2, 6)))]
    return sorted(floor, key=lambda c: _ORDER[c]), small, False


def _mode(rng: np.random.Generator, cat: str) -> str:
    if cat in ("bed", "sofa", "desk", "cabinet"):
        return "wall"
    if cat == "table":
        return "wall" if rng.random() < 0.3 else "free"
    return "wall" if rng.random() < 0.5 else "free"


def _sample_pose(rng: np.random.Generator, mode: str, lo_x: float, W: float, D: float) -> np.ndarray:
    if mode == "free":
        return F.yaw_pose(rng.uniform(0.3, W - 0.3), rng.uniform(0.3, D - 0.3), rng.uniform(-np.pi, np.pi))
    k = int(rng.integers(4))
    n = np.array(_WALL_NORMALS[k])
    p = _wall_point(k, rng.uniform(0.0, _wall_length(k, W, D)), W, D) + n * (0.02 - lo_x)
    return F.yaw_pose(p[0], p[1], float(np.arctan2(n[1], n[0])))


def _zone_rect(app: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local clear-zone rectangle: the approach square stretched to the nearest footprint point."""
    c = np.clip(app, lo, hi)
    pts = np.array([app - ZONE_HALF, app + ZONE_HALF, c - ZONE_HALF, c + ZONE_HALF])
    return pts.min(0), pts.max(0)


def _world_approach(obj: SceneObject) -> np.ndarray:
    a = np.asarray(obj.meta["approach"], dtype=np.float64)
    return obj.pose[:2, :2] @ a + obj.pose[:2, 3]


# ----------------------------------------------------------------------------- the room


def make_room(seed: int, size: tuple[float, float] | None = None, furniture: list[str] | None = None) -> Scene:
    """A furnished room; the same seed (and arguments) gives the same room.

    seed: int; size: (W, D) interior in m (default: uniform 4-7 m per side); furniture: floor and
    small categories to place (default: chosen per seed: a desk set or a table, 1-2 extra seats,
    often a bed or sofa, often a cabinet with drawers, 2-5 small objects). Returns a Scene with
    static meshes 'floor' and 'wall_0..3' (wall_k faces inward normal k: +y, -x, -y, +x) and the
    objects; Scene.meta holds seed, size, interior, wall_height, wall_thickness, door, skipped.
    Raises ValueError for bad arguments or when an explicitly requested piece does not fit.
    """
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise ValueError(f"seed must be an int, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    if size is None:
        W, D = (float(v) for v in rng.uniform(*ROOM_RANGE, size=2))
    else:
        try:
            size = tuple(float(v) for v in size)
        except (TypeError, ValueError):
            raise ValueError(f"size must be a pair (W, D) of numbers in m, got {size!r}") from None
        if len(size) != 2 or min(size) < 2.5 or max(size) > 20.0:
            raise ValueError(f"size must be (W, D) with each side in [2.5, 20] m, got {size!r}")
        W, D = float(size[0]), float(size[1])
    floor_cats, small_cats, explicit = _plan(rng, furniture)

    scene = Scene(name=f"room_{int(seed):04d}")
    T = WALL_THICKNESS
    scene.static["floor"] = F._box((-T - 0.05, -T - 0.05, -0.05), (W + T + 0.05, D + T + 0.05, 0.0))

    # --- door on a random wall
    dk = int(rng.integers(4))
    dr = F.door(rng, "door_0", T)
    wd, hd, th = dr.meta["width"], dr.meta["height"], dr.meta["thickness"]
    L = _wall_length(dk, W, D)
    t_d = float(rng.uniform(0.45 + wd / 2, L - 0.45 - wd / 2))
    n = np.array(_WALL_NORMALS[dk])
    depth = T - th / 2 - 0.005
    p = _wall_point(dk, t_d, W, D) - n * depth
    dr.pose = F.yaw_pose(p[0], p[1], float(np.arctan2(n[1], n[0])))
    for k in range(4):
        opening = (t_d - wd / 2 - 0.006, t_d + wd / 2 + 0.006, hd + 0.006) if k == dk else None
        scene.static[f"wall_{k}"] = _wall_mesh(k, W, D, opening)
    scene.objects[dr.name] = dr
    door_app = _world_approach(dr)
    dz_lo, dz_hi = np.array([depth, -wd / 2 - 0.25]), np.array([depth + 1.1, wd / 2 + 0.25])
    placed: list[_Placed] = [_Placed(quad=np.zeros((0, 2)), zone=_rect_quad(dz_lo, dz_hi, dr.pose))]
    footprints: list[_Footprint] = []
    approaches: list[np.ndarray] = []
    walk = _Walkable(W, D)
    free = walk.free & ~walk.blocked_by([])

    counters: dict[str, int] = {}

    def name_of(cat: str) -> str:
        i = counters.get(cat, 0)
        counters[cat] = i + 1
        return f"{cat}_{i}"

    surfaces: list[tuple[SceneObject, list[list[list[float]]]]] = []
    skipped: list[str] = []
    for cat in floor_cats:
        if cat == "desk":
            asm = F.desk_set(rng, name_of("desk"), name_of("chair"),
                             (name_of("keyboard"), name_of("mouse"), name_of("laptop")))
        elif cat == "cabinet":
            asm = F.cabinet(rng, name_of("cabinet"))
        else:
            asm = F.Assembly(getattr(F, cat)(rng, name_of(cat)))
        # exact footprints of the floor objects in the root frame, and their group bbox
        local_fps = [(asm.root, np.eye(4))] + [(o, rel) for o, rel in asm.attached if o.category in F.FLOOR_CATEGORIES]
        corners = np.concatenate([_rect_quad(*_local_rect(o), rel) for o, rel in local_fps])
        g_lo, g_hi = corners.min(0), corners.max(0)
        app = np.asarray(asm.root.meta["approach"], dtype=np.float64)
        z_lo, z_hi = _zone_rect(app, g_lo, g_hi)
        if cat in ("table", "cabinet"):  # keep the whole front free: small objects are reached there
            z_lo[1], z_hi[1] = min(z_lo[1], g_lo[1]), max(z_hi[1], g_hi[1])
        mode = _mode(rng, cat)
        ok = False
        for _ in range(ATTEMPTS):
            pose = _sample_pose(rng, mode, g_lo[0], W, D)
            quad, zone = _rect_quad(g_lo, g_hi, pose), _rect_quad(z_lo, z_hi, pose)
            if not (_inside(quad, W, D) and _inside(zone, W, D)):
                continue
            grown = _rect_quad(g_lo - MARGIN, g_hi + MARGIN, pose)
            if any(len(pl.quad) and (quads_overlap(grown, pl.quad) or quads_overlap(zone, pl.quad)) for pl in placed):
                continue
            if any(pl.zone is not None and quads_overlap(quad, pl.zone) for pl in placed):
                continue
            asm.place(pose)
            new_fps = [_Footprint(o.name, o.pose, *_local_rect(o)) for o, _ in local_fps]
            new_free = free & ~walk.blocked_by(new_fps)
            new_apps = [_world_approach(o) for o in asm.objects()]
            if not walk.connected(new_free, door_app, approaches + new_apps):
                continue
            free, ok = new_free, True
            footprints += new_fps
            approaches += new_apps
            placed.append(_Placed(quad=quad, zone=zone))
            break
        if not ok:
            if explicit:
                raise ValueError(f"could not place a {cat} in the {W:.2f} x {D:.2f} m room of seed {seed}; "
                                 f"give a larger size or fewer pieces")
            skipped.append(cat)
            continue
        for o in asm.objects():
            scene.objects[o.name] = o
        if cat in _SURFACES:
            surfaces.append((asm.root, [list(r) for r in asm.surface_items]))

    # --- small objects on surfaces (support frame, yaw of the support; flat ones jittered)
    labels, _ = ndimage.label(free)
    door_label = labels[walk.cell(door_app)]
    for cat in small_cats:
        obj = F.small_object(rng, name_of(cat), cat)
        if not surfaces:
            skipped.append(cat)
            continue
        ok = False
        for _ in range(40):
            sup, rects = surfaces[int(rng.integers(len(surfaces)))]
            sx, sy = sup.meta["surface_size"]
            yaw = float(rng.uniform(-0.4, 0.4)) if cat in ("phone", "book", "pen") else 0.0
            lo, hi = _local_rect(obj)
            q = _rect_quad(lo, hi, F.yaw_pose(0.0, 0.0, yaw))
            hx, hy = np.abs(q).max(0)
            mx, my = sx / 2 - hx - 0.03, sy / 2 - hy - 0.03
            if mx <= 0 or my <= 0:
                continue
            x, y = float(rng.uniform(-mx, mx)), float(rng.uniform(-my, my))
            r = [[x - hx, y - hy], [x + hx, y + hy]]
            if any(r[0][0] < b[1][0] + 0.02 and b[0][0] < r[1][0] + 0.02 and r[0][1] < b[1][1] + 0.02
                   and b[0][1] < r[1][1] + 0.02 for b in rects):
                continue
            rects.append(r)
            obj.pose = sup.pose @ F.yaw_pose(x, y, yaw, sup.meta["surface_height"])
            # stand in front of the support, abreast of the object if that spot is reachable
            a = np.asarray(sup.meta["approach"], dtype=np.float64)
            lim = max(0.0, sy / 2 - 0.25)
            a_w = sup.pose[:2, :2] @ [a[0], float(np.clip(y, -lim, lim))] + sup.pose[:2, 3]
            if labels[walk.cell(a_w)] != door_label:
                a_w = _world_approach(sup)
            loc = obj.pose[:2, :2].T @ (a_w - obj.pose[:2, 3])
            obj.meta["approach"] = F._f(loc)
            obj.meta["approach_yaw"] = F._f(np.angle(np.exp(1j * (sup.meta["approach_yaw"] - yaw))))
            obj.meta["support"] = sup.name
            scene.objects[obj.name] = obj
            ok = True
            break
        if not ok:
            if explicit:
                raise ValueError(f"no room left on any surface for a {cat} (seed {seed}); request fewer small objects")
            skipped.append(cat)

    scene.meta = {
        "seed": int(seed),
        "size": F._f([W, D]),
        "interior": F._f([[0.0, 0.0], [W, D]]),
        "wall_height": WALL_HEIGHT,
        "wall_thickness": WALL_THICKNESS,
        "door": dr.name,
        "door_wall": dk,
        "skipped": skipped,
    }
    return scene


# ----------------------------------------------------------------------------- queries


def floor_footprints(scene: Scene) -> dict[str, np.ndarray]:
    """World footprint quad (4, 2), m, of every floor-standing object (FLOOR_CATEGORIES)."""
    return {o.name: _rect_quad(*_local_rect(o), o.pose) for o in scene.objects.values()
            if o.category in F.FLOOR_CATEGORIES}


def approach_points(scene: Scene) -> dict[str, np.ndarray]:
    """World approach point (2,), m, of every object with meta 'approach'."""
    return {o.name: _world_approach(o) for o in scene.objects.values() if "approach" in o.meta}


def reachable_approaches(scene: Scene) -> dict[str, bool]:
    """Per object: is its approach point connected to the door's on the walkability grid
    (footprints and walls grown by BODY_RADIUS, CELL m cells, 4-connectivity)?"""
    W, D = scene.meta["size"]
    walk = _Walkable(W, D)
    fps = [_Footprint(o.name, o.pose, *_local_rect(o)) for o in scene.objects.values()
           if o.category in F.FLOOR_CATEGORIES]
    free = walk.free & ~walk.blocked_by(fps)
    lab, _ = ndimage.label(free)
    src = lab[walk.cell(_world_approach(scene.object(scene.meta["door"])))]
    return {k: bool(src > 0 and lab[walk.cell(p)] == src) for k, p in approach_points(scene).items()}
