"""Parametric furniture and small objects, built from trimesh primitives, with interaction meta.

Frames (the contract the motion code reads). Every mesh and every meta point is in the object's
LOCAL frame (world = pose @ point); meta yaws are relative to the object frame (world yaw =
object yaw + meta yaw). The local origin is the centre of the object's xy footprint at its bottom
(z = 0 is the lowest point; the door's origin is the centre of its leaf's bottom edge), and +x is
the object's *front*: a seated person faces +x of a chair, a person using a table, desk, cabinet or
door stands on its +x side facing -x.

Meta keys written for every object (metres / radians, plain JSON lists and floats):
``size`` [sx, sy, sz] bounding-box extents; ``approach`` [x, y] floor point where the person's
pelvis stands to interact; ``approach_yaw`` the direction the person faces there. Seats (chair,
stool, sofa, bed edge) use approach_yaw = sit_yaw (standing with the back to the seat, ready to
sit); everything else faces the object (approach_yaw = pi for front-facing objects).
Per category (see the builders' docstrings):
- chair / stool / sofa: ``seat_height``, ``seat_center`` [x, y, z] on the seat surface, ``sit_yaw``
  (direction the sitter faces, 0); chair also ``push_handles`` (two points on the backrest top);
  sofa also ``seat_centers`` (every place).
- sofa / bed: ``lie_center`` [x, y, z] on the cushion / mattress, ``lie_yaw`` (feet -> head),
  ``lie_length``. Bed also ``seat_*`` / ``sit_yaw`` on the edge of its free long side ``side``
  (+1: +y, -1: -y).
- table / desk / cabinet: ``surface_height``, ``surface_center`` [x, y, z], ``surface_size``
  [sx, sy]; cabinet also ``drawers`` (names, bottom to top).
- drawer: ``handle`` [x, y, z], ``max_travel`` (m along +x), ``parent`` (cabinet name), ``level``.
- door: ``handle``, ``max_angle``, ``open_sign`` (+-1.0), ``width``, ``height``, ``thickness``.
- bottle / cup / vase / phone / book / pen, keyboard / mouse / laptop: ``grasp_point`` (palm
  centre, on the surface), ``grasp_axis`` (unit direction the hand moves in to reach it),
  ``support`` (name of the table / desk / cabinet it stands on); keyboard and laptop
  ``press_points`` [[left hand], [right hand]] on the keys (for a person on the +x side facing
  -x, left = -y); mouse ``grip_point``; laptop ``screen_center``.

Meshes are unions of DISJOINT watertight primitives (boxes, 16-section cylinders, revolved
profiles) that touch or leave gaps of ~1 mm and never share a vertex, so every mesh is watertight
even after ``merge_vertices`` and splits into its primitives.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import trimesh

from trumans.scenes.scene import SceneObject

__all__ = [
    "Assembly",
    "SEAT_HEIGHT_RANGES",
    "FLOOR_CATEGORIES",
    "SMALL_CATEGORIES",
    "DESK_ITEM_CATEGORIES",
    "chair",
    "stool",
    "sofa",
    "bed",
    "table",
    "desk",
    "desk_set",
    "cabinet",
    "door",
    "small_object",
    "keyboard",
    "mouse",
    "laptop",
    "yaw_pose",
]

SECTIONS = 16  # cylinder / revolve sections: low poly
GAP = 0.001  # m, gap between adjacent parts so no two primitives share a vertex

#: seat-surface height ranges (m) per seat category
SEAT_HEIGHT_RANGES: dict[str, tuple[float, float]] = {
    "stool": (0.55, 0.75),
    "chair": (0.42, 0.50),
    "sofa": (0.38, 0.45),
    "bed": (0.40, 0.60),
}
#: categories that stand on the floor and own a footprint
FLOOR_CATEGORIES: tuple[str, ...] = ("chair", "stool", "sofa", "bed", "table", "desk", "cabinet")
#: free small objects placed on tables, desks and cabinets
SMALL_CATEGORIES: tuple[str, ...] = ("bottle", "cup", "phone", "book", "pen", "vase")
#: objects that come with every desk
DESK_ITEM_CATEGORIES: tuple[str, ...] = ("keyboard", "mouse", "laptop")


@dataclass
class Assembly:
    """A floor-standing piece and what comes with it.

    ``root`` is placed by the room generator; each ``attached`` entry is (object, root-from-object
    (4, 4) transform), so the attached object's world pose is ``root.pose @ transform``.
    ``surface_items`` lists, per attached object standing on the root's surface, its xy rectangle
    [[x0, y0], [x1, y1]] in the root frame (for later placement of further objects).
    """

    root: SceneObject
    attached: list[tuple[SceneObject, np.ndarray]] = field(default_factory=list)
    surface_items: list[list[list[float]]] = field(default_factory=list)

    def objects(self) -> list[SceneObject]:
        """Root first, then attached objects."""
        return [self.root] + [o for o, _ in self.attached]

    def place(self, pose: np.ndarray) -> None:
        """Set the root's world pose (4, 4) and every attached object's pose from it."""
        self.root.pose = np.asarray(pose, dtype=np.float64)
        for obj, rel in self.attached:
            obj.pose = self.root.pose @ rel


# ----------------------------------------------------------------------------- primitives


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    """Axis-aligned box between corners lo and hi (3,), m."""
    return trimesh.creation.box(bounds=np.array([lo, hi], dtype=np.float64))


def _cyl(radius: float, z0: float, z1: float, x: float = 0.0, y: float = 0.0) -> trimesh.Trimesh:
    """Vertical cylinder of ``radius`` from z0 to z1 centred at (x, y)."""
    m = trimesh.creation.cylinder(radius=radius, height=z1 - z0, sections=SECTIONS)
    m.apply_translation([x, y, 0.5 * (z0 + z1)])
    return m


def _revolve(profile: list[tuple[float, float]]) -> trimesh.Trimesh:
    """Solid of revolution about +z from a (radius, z) profile starting and ending on the axis."""
    return trimesh.creation.revolve(np.asarray(profile, dtype=np.float64), sections=SECTIONS)


def _assemble(parts: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """Concatenate disjoint watertight parts (no vertex merging across parts)."""
    return trimesh.util.concatenate(parts)


def yaw_pose(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """(4, 4) transform: rotation by ``yaw`` (rad) about +z, then translation (x, y, z) m."""
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:3, 3] = [x, y, z]
    return T


def _f(v) -> float | list:
    """Round to 0.1 mm and convert numpy values to plain JSON floats / lists."""
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0:
        return float(round(float(a), 4))
    return np.round(a, 4).tolist()


def _size(mesh: trimesh.Trimesh) -> list[float]:
    return _f(mesh.extents)


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform dimension in [lo, hi], quantised to 1 mm so meta (rounded to 0.1 mm) is exact."""
    return float(np.clip(round(float(rng.uniform(lo, hi)), 3), lo, hi))


# ----------------------------------------------------------------------------- seats


def chair(rng: np.random.Generator, name: str) -> SceneObject:
    """Four-legged chair with a backrest at -x; seat height 0.42-0.50 m; pushable (slide, any
    horizontal direction). Meta: seat_height, seat_center, sit_yaw = 0, push_handles [[x,y,z] x2]
    (top of the backrest, where hands push or pull)."""
    w, d = _u(rng, 0.42, 0.52), _u(rng, 0.42, 0.50)
    h = _u(rng, *SEAT_HEIGHT_RANGES["chair"])
    ts, tl, tb = 0.04, 0.04, 0.04  # seat, leg and backrest thickness
    hb = _u(rng, 0.35, 0.50)  # backrest height above the seat
    parts = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            cx, cy = sx * (d / 2 - 0.01 - tl / 2), sy * (w / 2 - 0.01 - tl / 2)
            parts.append(_box((cx - tl / 2, cy - tl / 2, 0.0), (cx + tl / 2, cy + tl / 2, h - ts)))
    parts.append(_box((-d / 2, -w / 2, h - ts), (d / 2, w / 2, h)))
    bx0 = -d / 2 + 0.005
    parts.append(_box((bx0, -w / 2 + 0.01, h), (bx0 + tb, w / 2 - 0.01, h + hb)))
    mesh = _assemble(parts)
    seat_x = 0.5 * ((bx0 + tb) + d / 2)
    meta = {
        "size": _size(mesh),
        "approach": _f([d / 2 + 0.20, 0.0]),
        "approach_yaw": 0.0,
        "seat_height": _f(h),
        "seat_center": _f([seat_x, 0.0, h]),
        "sit_yaw": 0.0,
        "push_handles": _f([[bx0 + tb / 2, -w / 2 + 0.08, h + hb], [bx0 + tb / 2, w / 2 - 0.08, h + hb]]),
    }
    return SceneObject(name, "chair", mesh, dof="slide", axis=None, dynamic=True, meta=meta)


def stool(rng: np.random.Generator, name: str) -> SceneObject:
    """Round bar stool on four legs, seat height 0.55-0.75 m, no backrest; pushable (slide).
    Meta: seat_height, seat_center (seat middle), sit_yaw = 0 (any direction works)."""
    r = _u(rng, 0.16, 0.20)
    h = _u(rng, *SEAT_HEIGHT_RANGES["stool"])
    ts, tl = 0.04, 0.03
    parts = [_cyl(r, h - ts, h)]
    rl = 0.62 * r
    for k in range(4):
        a = np.pi / 4 + k * np.pi / 2
        cx, cy = rl * np.cos(a), rl * np.sin(a)
        parts.append(_box((cx - tl / 2, cy - tl / 2, 0.0), (cx + tl / 2, cy + tl / 2, h - ts)))
    # footrest bars between neighbouring legs at 0.3 m (disjoint from legs by GAP)
    zf = 0.30
    for sx in (-1, 1):
        c = sx * rl * np.cos(np.pi / 4)
        parts.append(_box((c - 0.01, -abs(c) + tl / 2 + GAP, zf), (c + 0.01, abs(c) - tl / 2 - GAP, zf + 0.02)))
    mesh = _assemble(parts)
    meta = {
        "size": _size(mesh),
        "approach": _f([r + 0.20, 0.0]),
        "approach_yaw": 0.0,
        "seat_height": _f(h),
        "seat_center": _f([0.0, 0.0, h]),
        "sit_yaw": 0.0,
    }
    return SceneObject(name, "stool", mesh, dof="slide", axis=None, dynamic=True, meta=meta)


def sofa(rng: np.random.Generator, name: str) -> SceneObject:
    """Sofa 1.8-2.4 m wide (1.44-2.16 m between the arms): arms at +-y, backrest at -x, seat height
    0.38-0.45 m; static. Meta: seat_height, seat_center (middle place, 0.24 m behind the front
    edge), seat_centers (every place), sit_yaw = 0, lie_center (middle of the cushion), lie_yaw =
    +pi/2 (head towards +y), lie_length (between the arms)."""
    w, d = _u(rng, 1.8, 2.4), _u(rng, 0.80, 0.95)  # long enough to lie on (knees up if need be)
    h = _u(rng, *SEAT_HEIGHT_RANGES["sofa"])
    a, tb = _u(rng, 0.12, 0.18), _u(rng, 0.18, 0.24)
    ha, hb = h + _u(rng, 0.15, 0.22), h + _u(rng, 0.38, 0.48)
    yi = w / 2 - a - GAP
    parts = [
        _box((-d / 2, -w / 2, 0.0), (d / 2, -w / 2 + a, ha)),
        _box((-d / 2, w / 2 - a, 0.0), (d / 2, w / 2, ha)),
        _box((-d / 2, -yi, 0.0), (-d / 2 + tb, yi, hb)),
        _box((-d / 2 + tb + GAP, -yi, 0.0), (d / 2, yi, h)),
    ]
    mesh = _assemble(parts)
    sx = 0.5 * ((-d / 2 + tb) + d / 2)  # middle of the cushion (lying)
    st = d / 2 - 0.24  # sitting upright: near the front, so the thighs end at the front edge
    inner = 2 * yi
    n_places = max(2, int(inner // 0.6))
    ys = (np.arange(n_places) + 0.5) / n_places * inner - yi
    meta = {
        "size": _size(mesh),
        "approach": _f([d / 2 + 0.20, 0.0]),
        "approach_yaw": 0.0,
        "seat_height": _f(h),
        "seat_center": _f([st, 0.0, h]),
        "seat_centers": _f([[st, y, h] for y in ys]),
        "sit_yaw": 0.0,
        "lie_center": _f([sx, 0.0, h]),
        "lie_yaw": _f(np.pi / 2),
        "lie_length": _f(inner),
    }
    return SceneObject(name, "sofa", mesh, dof="static", dynamic=False, meta=meta)


def bed(rng: np.random.Generator, name: str) -> SceneObject:
    """Bed: length along x with the headboard at -x, mattress top 0.40-0.60 m; static.
    Meta: lie_center, lie_yaw = pi (feet at +x, head towards -x), lie_length; seat_center /
    seat_height / sit_yaw on the free long side (``side`` = +1 for +y, -1 for -y), where the
    approach point is."""
    L, wb = _u(rng, 1.95, 2.15), float(rng.choice([0.9, 1.2, 1.4, 1.6, 1.8])) + _u(rng, 0.0, 0.05)
    hm = _u(rng, *SEAT_HEIGHT_RANGES["bed"])
    th, hh = 0.06, hm + _u(rng, 0.35, 0.60)
    hbase = hm - 0.2
    x0 = -L / 2 + th + GAP
    parts = [
        _box((-L / 2, -wb / 2, 0.0), (-L / 2 + th, wb / 2, hh)),
        _box((x0, -wb / 2, 0.0), (L / 2, wb / 2, hbase)),
        _box((x0 + 0.02, -wb / 2 + 0.02, hbase), (L / 2 - 0.02, wb / 2 - 0.02, hm)),
    ]
    mesh = _assemble(parts)
    side = float(rng.choice([-1.0, 1.0]))
    mx0, mx1 = x0 + 0.02, L / 2 - 0.02
    sit_x = 0.5 * (mx0 + mx1) + 0.1
    meta = {
        "size": _size(mesh),
        "approach": _f([sit_x, side * (wb / 2 + 0.20)]),
        "approach_yaw": _f(side * np.pi / 2),
        "seat_height": _f(hm),
        "seat_center": _f([sit_x, side * (wb / 2 - 0.20), hm]),
        "sit_yaw": _f(side * np.pi / 2),
        "side": side,
        "lie_center": _f([0.5 * (mx0 + mx1), 0.0, hm]),
        "lie_yaw": _f(np.pi),
        "lie_length": _f(mx1 - mx0),
    }
    return SceneObject(name, "bed", mesh, dof="static", dynamic=False, meta=meta)


# ----------------------------------------------------------------------------- surfaces


def _surface_meta(mesh: trimesh.Trimesh, sx: float, sy: float, h: float, approach_dx: float) -> dict:
    return {
        "size": _size(mesh),
        "approach": _f([sx / 2 + approach_dx, 0.0]),
        "approach_yaw": _f(np.pi),
        "surface_height": _f(h),
        "surface_center": _f([0.0, 0.0, h]),
        "surface_size": _f([sx, sy]),
    }


def table(rng: np.random.Generator, name: str) -> SceneObject:
    """Four-legged table, top 0.70-0.78 m. Half of the tables are pushable (slide, any horizontal
    direction, dynamic), the rest static. Meta: surface_height, surface_center, surface_size."""
    sx, sy = _u(rng, 0.70, 1.00), _u(rng, 0.90, 1.60)
    h, tt, tl, inset = _u(rng, 0.70, 0.78), 0.035, 0.05, 0.04
    parts = [_box((-sx / 2, -sy / 2, h - tt), (sx / 2, sy / 2, h))]
    for kx in (-1, 1):
        for ky in (-1, 1):
            cx, cy = kx * (sx / 2 - inset - tl / 2), ky * (sy / 2 - inset - tl / 2)
            parts.append(_box((cx - tl / 2, cy - tl / 2, 0.0), (cx + tl / 2, cy + tl / 2, h - tt)))
    mesh = _assemble(parts)
    meta = _surface_meta(mesh, sx, sy, h, 0.30)
    if rng.random() < 0.5:
        return SceneObject(name, "table", mesh, dof="slide", axis=None, dynamic=True, meta=meta)
    return SceneObject(name, "table", mesh, dof="static", dynamic=False, meta=meta)


def desk(rng: np.random.Generator, name: str) -> SceneObject:
    """Desk on two side panels with a modesty panel at the back, top 0.72-0.76 m; static.
    Meta: surface_height, surface_center, surface_size; approach 0.25 m in front of the top."""
    sx, sy = _u(rng, 0.60, 0.75), _u(rng, 1.10, 1.60)
    h, tt, tp = _u(rng, 0.72, 0.76), 0.03, 0.025
    parts = [_box((-sx / 2, -sy / 2, h - tt), (sx / 2, sy / 2, h))]
    for ky in (-1, 1):
        y0 = ky * (sy / 2 - 0.01)
        y1 = ky * (sy / 2 - 0.01 - tp)
        parts.append(_box((-sx / 2 + 0.02, min(y0, y1), 0.0), (sx / 2 - 0.02, max(y0, y1), h - tt)))
    yi = sy / 2 - 0.01 - tp - GAP
    parts.append(_box((-sx / 2 + 0.04, -yi, 0.25), (-sx / 2 + 0.04 + 0.018, yi, h - tt - GAP)))
    mesh = _assemble(parts)
    meta = _surface_meta(mesh, sx, sy, h, 0.25)
    return SceneObject(name, "desk", mesh, dof="static", dynamic=False, meta=meta)


def cabinet(rng: np.random.Generator, name: str) -> Assembly:
    """Cabinet (static carcass, front at +x) with 2-3 stacked drawers, each its own object
    (category 'drawer', dof slide along local +x, dynamic). Cabinet meta: surface_* (its top),
    drawers (names, bottom to top). Drawer meta: handle, max_travel (0.3-0.4 m), parent, level."""
    w, d, h = _u(rng, 0.60, 1.00), _u(rng, 0.45, 0.55), _u(rng, 0.70, 1.05)
    n = int(rng.integers(2, 4))
    t, plinth = 0.018, 0.08
    yi = w / 2 - t - GAP
    xb = -d / 2 + t + GAP  # front face of the back panel + gap
    parts = [
        _box((-d / 2, -w / 2, 0.0), (d / 2, -w / 2 + t, h)),
        _box((-d / 2, w / 2 - t, 0.0), (d / 2, w / 2, h)),
        _box((xb, -yi, h - t), (d / 2, yi, h)),
        _box((xb, -yi, 0.0), (d / 2 - 0.03, yi, plinth)),
        _box((-d / 2, -yi, plinth + GAP), (-d / 2 + t, yi, h - t - GAP)),
    ]
    hd = (h - t - plinth - (n - 1) * t) / n  # opening height per drawer
    z_open = [plinth + k * (hd + t) for k in range(n)]
    for k in range(1, n):
        parts.append(_box((xb, -yi, z_open[k] - t), (d / 2, yi, z_open[k])))
    mesh = _assemble(parts)
    meta = _surface_meta(mesh, d, w, h, 0.60)
    meta["drawers"] = [f"{name}_drawer_{k}" for k in range(n)]
    root = SceneObject(name, "cabinet", mesh, dof="static", dynamic=False, meta=meta)
    asm = Assembly(root)

    # drawer k: tray of 5 boxes + handle, local origin at the centre of its footprint bottom
    wd, dd, clear = w - 2 * t - 0.008, d - t - 0.02, 0.004
    hk = hd - 2 * clear
    tf, tw = 0.018, 0.012  # front panel, tray wall thickness
    xf = dd / 2 - tf  # back face of the front panel
    zw = 0.8 * hk
    tray = [
        _box((xf, -wd / 2, 0.0), (dd / 2, wd / 2, hk)),
        _box((-dd / 2, -wd / 2, 0.0), (xf - GAP, wd / 2, tw)),
        _box((-dd / 2, -wd / 2, tw + GAP), (xf - GAP, -wd / 2 + tw, zw)),
        _box((-dd / 2, wd / 2 - tw, tw + GAP), (xf - GAP, wd / 2, zw)),
        _box((-dd / 2, -wd / 2 + tw + GAP, tw + GAP), (-dd / 2 + tw, wd / 2 - tw - GAP, zw)),
        _box((dd / 2, -0.06, hk / 2 - 0.01), (dd / 2 + 0.025, 0.06, hk / 2 + 0.01)),
    ]
    dmesh = _assemble(tray)
    x_c = d / 2 - dd / 2
    travel = float(np.clip(0.75 * dd, 0.30, 0.40))
    for k in range(n):
        dname = meta["drawers"][k]
        dmeta = {
            "size": _size(dmesh),
            # the cabinet's approach point in the drawer frame: in front of the fully open drawer
            "approach": _f([d / 2 + 0.60 - x_c, 0.0]),
            "approach_yaw": _f(np.pi),
            "handle": _f([dd / 2 + 0.0125, 0.0, hk / 2]),
            "max_travel": _f(travel),
            "parent": name,
            "level": k,
        }
        obj = SceneObject(dname, "drawer", dmesh.copy(), dof="slide", axis=np.array([1.0, 0.0, 0.0]),
                          dynamic=True, meta=dmeta)
        asm.attached.append((obj, yaw_pose(x_c, 0.0, 0.0, z_open[k] + clear)))
    return asm


# ----------------------------------------------------------------------------- door


def door(rng: np.random.Generator, name: str, wall_thickness: float) -> SceneObject:
    """Door leaf (thin box in the local y-z plane) with a lever handle on its +x (room) face; the
    door opens INTO the room (+x), pulled open by the handle and pushed closed.

    Hinge: vertical axis [0, 0, 1] through hinge_point = (th/2, hinge_side * w/2, 0) on the +x
    face. Opening angle = open_sign * a, a in [0, max_angle]; positive a swings the free edge
    towards +x, through the clear zone the room keeps in front of the door (``trumans.scenes.procedural``).
    Meta: handle, max_angle, open_sign, width, height, thickness; approach on the +x side facing
    the door."""
    w, hgt, th = _u(rng, 0.80, 0.92), _u(rng, 2.00, 2.10), 0.04
    hinge_side = float(rng.choice([-1.0, 1.0]))
    y_handle = -hinge_side * (w / 2 - 0.08)
    parts = [
        _box((-th / 2, -w / 2, 0.0), (th / 2, w / 2, hgt)),
        _box((th / 2, y_handle - 0.06, 1.0 - 0.012), (th / 2 + 0.06, y_handle + 0.06, 1.0 + 0.012)),
    ]
    mesh = _assemble(parts)
    depth = wall_thickness - th / 2 - 0.005  # leaf centre to the room side of the wall
    meta = {
        "size": _size(mesh),
        "approach": _f([depth + 0.55, 0.5 * y_handle]),
        "approach_yaw": _f(np.pi),
        "handle": _f([th / 2 + 0.045, y_handle, 1.0]),
        "max_angle": 1.4,
        "open_sign": hinge_side,
        "width": _f(w),
        "height": _f(hgt),
        "thickness": th,
    }
    return SceneObject(name, "door", mesh, dof="hinge", hinge_point=np.array([th / 2, hinge_side * w / 2, 0.0]),
                       axis=np.array([0.0, 0.0, 1.0]), dynamic=True, meta=meta)


# ----------------------------------------------------------------------------- small objects


def small_object(rng: np.random.Generator, name: str, category: str) -> SceneObject:
    """A free graspable object (one of SMALL_CATEGORIES) standing on z = 0.

    Upright objects (bottle, cup, vase) are grasped from the side: grasp_point on the +x surface,
    grasp_axis [-1, 0, 0]; flat ones (phone, book, pen) from above: grasp_point on the top,
    grasp_axis [0, 0, -1]. ``support`` is filled in when the object is placed."""
    if category == "bottle":
        r, hb, hn = _u(rng, 0.028, 0.040), _u(rng, 0.14, 0.22), _u(rng, 0.05, 0.08)
        rn = 0.4 * r
        mesh = _revolve([(0, 0), (r, 0), (r, hb), (rn, hb + 0.03), (rn, hb + 0.03 + hn), (0, hb + 0.03 + hn)])
        grasp, axis = [r, 0.0, 0.55 * hb], [-1.0, 0.0, 0.0]
    elif category == "cup":
        r, h = _u(rng, 0.035, 0.045), _u(rng, 0.08, 0.11)
        mesh = _revolve([(0, 0), (0.8 * r, 0), (r, h), (0, h)])
        grasp, axis = [0.9 * r, 0.0, 0.5 * h], [-1.0, 0.0, 0.0]
    elif category == "vase":
        r, h = _u(rng, 0.06, 0.09), _u(rng, 0.20, 0.35)
        rn = 0.45 * r
        mesh = _revolve([(0, 0), (0.7 * r, 0), (r, 0.35 * h), (rn, 0.8 * h), (0.6 * r, h), (0, h)])
        grasp, axis = [rn, 0.0, 0.8 * h], [-1.0, 0.0, 0.0]
    elif category == "phone":
        sx, sy, sz = _u(rng, 0.07, 0.08), _u(rng, 0.14, 0.16), 0.008
        mesh = _box((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, sz))
        grasp, axis = [0.0, 0.0, sz], [0.0, 0.0, -1.0]
    elif category == "book":
        sx, sy, sz = _u(rng, 0.15, 0.22), _u(rng, 0.20, 0.28), _u(rng, 0.02, 0.05)
        mesh = _box((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, sz))
        grasp, axis = [0.0, 0.0, sz], [0.0, 0.0, -1.0]
    elif category == "pen":
        r, ln = 0.005, _u(rng, 0.13, 0.15)
        mesh = trimesh.creation.cylinder(radius=r, height=ln, sections=SECTIONS)
        mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
        mesh.apply_translation([0, 0, r])
        grasp, axis = [0.0, 0.0, 2 * r], [0.0, 0.0, -1.0]
    else:
        raise ValueError(f"small_object: category must be one of {SMALL_CATEGORIES}, got {category!r}")
    meta = {"size": _size(mesh), "approach": [0.0, 0.0], "approach_yaw": _f(np.pi),
            "grasp_point": _f(grasp), "grasp_axis": _f(axis), "support": ""}
    return SceneObject(name, category, mesh, dof="free", dynamic=True, meta=meta)


def keyboard(rng: np.random.Generator, name: str) -> SceneObject:
    """Keyboard (box), user on its +x side. Meta: press_points [[left hand], [right hand]] on the
    key surface (left = -y for a user facing -x), grasp_point / grasp_axis (from above)."""
    sx, sy, sz = _u(rng, 0.13, 0.16), _u(rng, 0.42, 0.46), _u(rng, 0.02, 0.03)
    mesh = _box((-sx / 2, -sy / 2, 0.0), (sx / 2, sy / 2, sz))
    meta = {"size": _size(mesh), "approach": [0.0, 0.0], "approach_yaw": _f(np.pi),
            "press_points": _f([[0.0, -0.10, sz], [0.0, 0.10, sz]]),
            "grasp_point": _f([0.0, 0.0, sz]), "grasp_axis": [0.0, 0.0, -1.0], "support": ""}
    return SceneObject(name, "keyboard", mesh, dof="free", dynamic=True, meta=meta)


def mouse(rng: np.random.Generator, name: str) -> SceneObject:
    """Computer mouse (flattened capsule along x). Meta: grip_point (palm centre on the top),
    grasp_point (= grip_point), grasp_axis [0, 0, -1]."""
    r, ln = 0.03, _u(rng, 0.045, 0.055)
    mesh = trimesh.creation.capsule(height=ln, radius=r, count=[SECTIONS, SECTIONS // 2])
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    mesh.apply_scale([1.0, 1.0, 0.6])
    mesh.apply_translation([0.0, 0.0, -mesh.bounds[0, 2]])
    top = float(mesh.bounds[1, 2])
    meta = {"size": _size(mesh), "approach": [0.0, 0.0], "approach_yaw": _f(np.pi),
            "grip_point": _f([0.01, 0.0, top]), "grasp_point": _f([0.01, 0.0, top]),
            "grasp_axis": [0.0, 0.0, -1.0], "support": ""}
    return SceneObject(name, "mouse", mesh, dof="free", dynamic=True, meta=meta)


def laptop(rng: np.random.Generator, name: str) -> SceneObject:
    """Open laptop: base slab plus a screen tilted back ~15-25 deg behind it (user on +x).
    Meta: press_points [[left], [right]] on the base's keys, screen_center, grasp_point on the
    base's front edge with grasp_axis [-1, 0, 0]."""
    bx, by, bz = _u(rng, 0.22, 0.25), _u(rng, 0.31, 0.36), 0.018
    sh, st, tilt = bx * _u(rng, 0.95, 1.05), 0.008, _u(rng, np.radians(15), np.radians(25))
    base = _box((-bx / 2, -by / 2, 0.0), (bx / 2, by / 2, bz))
    # screen: box x in [0, st] (pivot = its bottom-back edge at x = 0), rotated back by tilt
    scr = _box((0.0, -by / 2, 0.0), (st, by / 2, sh))
    rot = trimesh.transformations.rotation_matrix(-tilt, [0, 1, 0])  # top moves towards -x
    scr.apply_transform(rot)
    scr.apply_translation([-bx / 2 - st - GAP, 0.0, 0.0])
    mesh = _assemble([base, scr])
    c = mesh.bounds.mean(axis=0)
    shift = np.array([-c[0], -c[1], -mesh.bounds[0, 2]])
    mesh.apply_translation(shift)
    scr_c = np.array([-bx / 2 - st - GAP - 0.5 * sh * np.sin(tilt), 0.0, 0.5 * sh * np.cos(tilt)]) + shift
    meta = {"size": _size(mesh), "approach": [0.0, 0.0], "approach_yaw": _f(np.pi),
            "press_points": _f([[shift[0] + 0.02, -0.07, bz + shift[2]], [shift[0] + 0.02, 0.07, bz + shift[2]]]),
            "screen_center": _f(scr_c),
            "grasp_point": _f([shift[0] + bx / 2, 0.0, shift[2] + bz / 2]), "grasp_axis": [-1.0, 0.0, 0.0],
            "support": ""}
    return SceneObject(name, "laptop", mesh, dof="free", dynamic=True, meta=meta)


def desk_set(rng: np.random.Generator, name: str, chair_name: str,
             item_names: tuple[str, str, str] = ("keyboard_0", "mouse_0", "laptop_0")) -> Assembly:
    """A desk with its chair tucked in front (chair facing the desk, 0.45 m gap between the chair's
    front edge and the desk's front edge) and a keyboard, mouse and laptop on top.

    The chair is a floor object of its own (pose = desk pose @ transform); its approach point lies
    in the gap, at the desk's approach point. Items get ``support`` = desk name and the desk's
    approach point converted to their frame; ``item_names`` names (keyboard, mouse, laptop)."""
    dsk = desk(rng, name)
    asm = Assembly(dsk)
    sx, sy = dsk.meta["surface_size"]
    h = dsk.meta["surface_height"]
    ch = chair(rng, chair_name)
    cd = ch.meta["size"][0]
    gap = 0.45
    # chair local +x points to desk -x: yaw pi; chair centre along desk +x
    cx = sx / 2 + gap + cd / 2
    asm.attached.append((ch, yaw_pose(cx, 0.0, np.pi)))
    # chair approach (chair frame) d/2 + 0.2 -> desk frame sx/2 + gap - 0.2; set the desk's to it
    dsk.meta["approach"] = _f([sx / 2 + gap - 0.20, 0.0])
    kb, ms, lp = keyboard(rng, item_names[0]), mouse(rng, item_names[1]), laptop(rng, item_names[2])
    kx = sx / 2 - 0.04 - kb.meta["size"][0] / 2
    ky = float(rng.uniform(-0.08, 0.08))
    my = ky + kb.meta["size"][1] / 2 + 0.08
    lx = -sx / 2 + 0.04 + lp.meta["size"][0] / 2
    ly = float(np.clip(ky - 0.15 + rng.uniform(-0.1, 0.1), -sy / 2 + 0.2, sy / 2 - 0.2))
    for obj, x, y in ((kb, kx, ky), (ms, kx, my), (lp, lx, ly)):
        rel = yaw_pose(x, y, 0.0, h)
        a = np.asarray(dsk.meta["approach"])
        obj.meta["approach"] = _f(a - [x, y])
        obj.meta["approach_yaw"] = dsk.meta["approach_yaw"]
        obj.meta["support"] = name
        asm.attached.append((obj, rel))
        hx, hy = obj.meta["size"][0] / 2, obj.meta["size"][1] / 2
        asm.surface_items.append(_f([[x - hx, y - hy], [x + hx, y + hy]]))
    return asm
