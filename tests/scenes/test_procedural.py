"""Procedural rooms and parametric furniture: determinism, geometry invariants and the meta contract."""
from __future__ import annotations

import json
from collections import Counter

import numpy as np
import pytest
import trimesh

from trumans.scenes import furniture as F
from trumans.scenes.procedural import (
    quads_overlap,
    approach_points,
    floor_footprints,
    list_categories,
    make_room,
    reachable_approaches,
)

SEEDS = range(30)


@pytest.fixture(scope="module")
def rooms():
    return [make_room(s) for s in SEEDS]


def _local(obj, p_world: np.ndarray) -> np.ndarray:
    """World (..., 3) point -> object frame."""
    inv = np.linalg.inv(obj.pose)
    return p_world @ inv[:3, :3].T + inv[:3, 3]


def _world(obj, p_local) -> np.ndarray:
    p = np.asarray(p_local, dtype=np.float64)
    return p @ obj.pose[:3, :3].T + obj.pose[:3, 3]


def _down_hit_z(mesh: trimesh.Trimesh, xy, z_from: float) -> float:
    """z of the first surface hit by a ray cast straight down from (x, y, z_from)."""
    loc, _, _ = mesh.ray.intersects_location([[xy[0], xy[1], z_from]], [[0.0, 0.0, -1.0]])
    assert len(loc), f"no surface below {xy}"
    return float(loc[:, 2].max())


def test_determinism_and_variety():
    a, b, c = make_room(7), make_room(7), make_room(8)
    assert a.name == "room_0007" and list(a.objects) == list(b.objects)
    assert json.dumps(a.meta) == json.dumps(b.meta)
    for k, o in a.objects.items():
        p = b.objects[k]
        assert o.category == p.category and o.dof == p.dof
        np.testing.assert_array_equal(o.pose, p.pose)
        np.testing.assert_array_equal(o.mesh.vertices, p.mesh.vertices)
        assert json.dumps(o.meta) == json.dumps(p.meta)
    assert a.meta["size"] != c.meta["size"]


def test_room_shell(rooms):
    for sc in rooms:
        W, D = sc.meta["size"]
        assert 4.0 <= W <= 7.0 and 4.0 <= D <= 7.0
        assert set(sc.static) == {"floor", "wall_0", "wall_1", "wall_2", "wall_3"}
        fb = sc.static["floor"].bounds
        assert abs(fb[1, 2]) < 1e-9 and fb[0, 2] < 0
        for k in range(4):
            wb = sc.static[f"wall_{k}"].bounds
            assert abs(wb[1, 2] - 2.6) < 1e-9 and abs(wb[0, 2]) < 1e-9
        # the door's wall has an opening: a horizontal ray through the door centre at 1 m misses it
        door = sc.object(sc.meta["door"])
        wall = sc.static[f"wall_{sc.meta['door_wall']}"]
        start = _world(door, [1.0, 0.0, 1.0])
        direction = door.pose[:3, :3] @ np.array([-1.0, 0.0, 0.0])
        hits, _, _ = wall.ray.intersects_location([start], [direction])
        assert len(hits) == 0
        # ... while the same ray beside the opening hits the wall
        beside = _world(door, [1.0, door.meta["width"] / 2 + 0.2, 1.0])
        if 0.2 < beside[0] < W - 0.2 and 0.2 < beside[1] < D - 0.2:
            hits, _, _ = wall.ray.intersects_location([beside], [direction])
            assert len(hits) > 0


def _quads_overlap_by_sampling(qa: np.ndarray, qb: np.ndarray, n: int = 25) -> bool:
    """Independent check: lattice points strictly inside qa that fall strictly inside qb."""
    u = (np.arange(n) + 0.5) / n
    s, t = np.meshgrid(u, u, indexing="ij")
    pts = (qa[0] + s[..., None] * (qa[1] - qa[0]) + t[..., None] * (qa[3] - qa[0])).reshape(-1, 2)
    e1, e2 = qb[1] - qb[0], qb[3] - qb[0]
    a = (pts - qb[0]) @ e1 / (e1 @ e1)
    b = (pts - qb[0]) @ e2 / (e2 @ e2)
    return bool(np.any((a > 1e-4) & (a < 1 - 1e-4) & (b > 1e-4) & (b < 1 - 1e-4)))


def test_sat_analytic():
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    assert quads_overlap(sq, sq + 0.5)
    assert not quads_overlap(sq, sq + [1.0, 0.0])  # touching edges
    assert not quads_overlap(sq, sq + [1.01, 1.01])
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    diamond = (sq - 0.5) @ np.array([[c, -s], [s, c]]).T + [1.0 + 0.5 * np.sqrt(2) + 0.01, 0.5]
    assert not quads_overlap(sq, diamond)
    assert quads_overlap(sq, diamond - [0.05, 0.0])
    assert _quads_overlap_by_sampling(sq, sq + 0.5) and not _quads_overlap_by_sampling(sq, sq + [1.0, 0.0])


def test_no_overlapping_footprints(rooms):
    for sc in rooms:
        fps = floor_footprints(sc)
        names = list(fps)
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                assert not quads_overlap(fps[a], fps[b]), (sc.name, a, b)
                assert not _quads_overlap_by_sampling(fps[a], fps[b]), (sc.name, a, b)


def test_approach_points_free_and_reachable(rooms):
    for sc in rooms:
        W, D = sc.meta["size"]
        fps = floor_footprints(sc)
        for name, p in approach_points(sc).items():
            assert 0.15 < p[0] < W - 0.15 and 0.15 < p[1] < D - 0.15, (sc.name, name, p)
            for f, q in fps.items():
                e1, e2 = q[1] - q[0], q[3] - q[0]
                a, b = (p - q[0]) @ e1 / (e1 @ e1), (p - q[0]) @ e2 / (e2 @ e2)
                assert not (0 <= a <= 1 and 0 <= b <= 1), (sc.name, name, "inside", f)
        reach = reachable_approaches(sc)
        assert reach and all(reach.values()), (sc.name, reach)


def test_every_category_appears(rooms):
    counts = Counter(o.category for sc in rooms for o in sc.objects.values())
    assert set(counts) == set(list_categories())
    assert min(counts.values()) >= 5, counts
    for sc in rooms:
        cats = Counter(o.category for o in sc.objects.values())
        assert cats["door"] == 1
        assert cats["table"] + cats["desk"] >= 1
        assert cats["chair"] + cats["stool"] + cats["sofa"] >= 1
        small = sum(cats[c] for c in F.SMALL_CATEGORIES)
        assert small <= 5
        if cats["desk"]:
            for c in ("keyboard", "mouse", "laptop"):
                assert cats[c] == cats["desk"]
    small_total = sum(counts[c] for c in F.SMALL_CATEGORIES)
    assert small_total >= 2 * len(rooms) - 3  # 2-5 per room; at most a few skipped


def test_meshes_watertight_and_low_poly(rooms):
    for sc in rooms[:10]:
        meshes = {k: m for k, m in sc.static.items()} | {k: o.mesh for k, o in sc.objects.items()}
        for k, m in meshes.items():
            assert len(m.faces) > 0 and len(m.faces) < 5000, (k, len(m.faces))
            assert m.is_watertight, k
            merged = m.copy()
            merged.merge_vertices()
            assert merged.is_watertight, f"{k}: parts share vertices"
            assert all(p.is_volume for p in merged.split(only_watertight=False)), k


def test_objects_sit_on_the_floor_or_their_support(rooms):
    for sc in rooms:
        for o in sc.objects.values():
            assert abs(o.mesh.bounds[0, 2]) < 1e-9, (o.name, "local bottom must be z = 0")
            wb = o.world_mesh().bounds
            if o.category in F.FLOOR_CATEGORIES or o.category == "door":
                assert abs(wb[0, 2]) < 1e-6, o.name
            elif o.category in F.SMALL_CATEGORIES + F.DESK_ITEM_CATEGORIES:
                sup = sc.object(o.meta["support"])
                assert sup.category in ("table", "desk", "cabinet")
                assert abs(wb[0, 2] - sup.meta["surface_height"]) < 1e-3, o.name
                # its footprint lies on the support's top
                c = _local(sup, o.world_mesh().vertices)
                sx, sy = sup.meta["surface_size"]
                assert np.all(np.abs(c[:, 0]) <= sx / 2 + 0.06) and np.all(np.abs(c[:, 1]) <= sy / 2 + 1e-6), o.name


def test_seat_lie_and_surface_meta_match_the_mesh(rooms):
    ranges = F.SEAT_HEIGHT_RANGES
    seen = set()
    for sc in rooms:
        for o in sc.objects.values():
            m = o.meta
            if "seat_height" in m:
                lo, hi = ranges[o.category]
                assert lo <= m["seat_height"] <= hi, (o.name, m["seat_height"])
                sc_ = m["seat_center"]
                assert abs(sc_[2] - m["seat_height"]) < 1e-6
                assert abs(_down_hit_z(o.mesh, sc_[:2], 3.0) - m["seat_height"]) < 1e-3, o.name
                seen.add(o.category)
            if "lie_center" in m:
                lc = m["lie_center"]
                assert abs(_down_hit_z(o.mesh, lc[:2], 3.0) - lc[2]) < 1e-3, o.name
                # the lying line (lie_length along lie_yaw) stays on the cushion/mattress
                d = np.array([np.cos(m["lie_yaw"]), np.sin(m["lie_yaw"])])
                for s in (-0.45, 0.45):
                    xy = np.asarray(lc[:2]) + s * m["lie_length"] * d
                    assert abs(_down_hit_z(o.mesh, xy, lc[2] + 0.01) - lc[2]) < 1e-3, o.name
            if "surface_height" in m:
                sc_ = m["surface_center"]
                assert abs(_down_hit_z(o.mesh, sc_[:2], 3.0) - m["surface_height"]) < 1e-3, o.name
                assert abs(o.mesh.bounds[1, 2] - m["surface_height"]) < 1e-6
    assert seen == {"chair", "stool", "sofa", "bed"}


REQUIRED = {
    "chair": {"seat_height", "seat_center", "sit_yaw", "push_handles"},
    "stool": {"seat_height", "seat_center", "sit_yaw"},
    "sofa": {"seat_height", "seat_center", "sit_yaw", "lie_center", "lie_yaw", "lie_length"},
    "bed": {"seat_height", "seat_center", "sit_yaw", "lie_center", "lie_yaw", "lie_length"},
    "table": {"surface_height", "surface_center", "surface_size"},
    "desk": {"surface_height", "surface_center", "surface_size"},
    "cabinet": {"surface_height", "surface_center", "surface_size", "drawers"},
    "drawer": {"handle", "max_travel", "parent", "level"},
    "door": {"handle", "max_angle", "open_sign", "width", "height"},
    "keyboard": {"press_points", "support", "grasp_point", "grasp_axis"},
    "mouse": {"grip_point", "support", "grasp_point", "grasp_axis"},
    "laptop": {"press_points", "support", "grasp_point", "grasp_axis"},
} | {c: {"grasp_point", "grasp_axis", "support"} for c in F.SMALL_CATEGORIES}


def test_meta_keys_dofs_and_axes(rooms):
    for sc in rooms:
        json.dumps(sc.meta)
        for o in sc.objects.values():
            m = o.meta
            json.dumps(m)
            assert {"size", "approach", "approach_yaw"} <= set(m), o.name
            assert REQUIRED[o.category] <= set(m), (o.name, REQUIRED[o.category] - set(m))
            np.testing.assert_allclose(m["size"], o.mesh.extents, atol=1e-3)
            if o.category == "chair":
                assert o.dof == "slide" and o.axis is None and o.dynamic
            if o.category in ("bed", "sofa", "cabinet", "desk"):
                assert o.dof == "static" and not o.dynamic
            if o.category == "table":
                assert (o.dof, o.dynamic) in {("static", False), ("slide", True)}
            if o.category == "drawer":
                assert o.dof == "slide" and o.dynamic
                np.testing.assert_allclose(o.axis, [1.0, 0.0, 0.0])
                assert 0.3 <= m["max_travel"] <= 0.4
                parent = sc.object(m["parent"])
                assert parent.category == "cabinet" and o.name in parent.meta["drawers"]
                # drawer frame has the cabinet's orientation; its handle is at the front (+x)
                np.testing.assert_allclose(o.pose[:3, :3], parent.pose[:3, :3], atol=1e-9)
                assert abs(m["handle"][0] - o.mesh.bounds[1, 0]) < 0.03
            if o.category == "door":
                assert o.dof == "hinge" and o.dynamic and o.hinge_point is not None
                np.testing.assert_allclose(o.axis, [0.0, 0.0, 1.0])
                assert m["open_sign"] in (-1.0, 1.0) and 1.2 <= m["max_angle"] <= 1.6
            if o.category in F.SMALL_CATEGORIES + F.DESK_ITEM_CATEGORIES:
                assert o.dof == "free" and o.dynamic
                assert abs(np.linalg.norm(m["grasp_axis"]) - 1.0) < 1e-6
                # the grasp point is on the object's surface
                _, dist, _ = trimesh.proximity.closest_point(o.mesh, [m["grasp_point"]])
                assert dist[0] < 0.01, (o.name, dist)
            if o.category in ("keyboard", "laptop"):
                (l, r) = m["press_points"]
                assert l[1] < r[1]  # left hand at -y for a user on +x facing -x
                assert abs(_down_hit_z(o.mesh, l[:2], 1.0) - l[2]) < 1e-3


def test_door_swings_into_the_room_clear_of_furniture(rooms):
    for sc in rooms[:12]:
        door = sc.object(sc.meta["door"])
        m = door.meta
        handle = np.asarray(m["handle"])
        assert handle[0] > m["thickness"] / 2 - 1e-9  # handle on the +x (room) face
        W, D = sc.meta["size"]
        T = sc.meta["wall_thickness"]
        fps = floor_footprints(sc)
        lo, hi = door.mesh.bounds[0, :2], door.mesh.bounds[1, :2]
        for a in np.linspace(0.1, m["max_angle"], 6):
            R = trimesh.transformations.rotation_matrix(m["open_sign"] * a, door.axis, door.hinge_point)
            moved = R[:3, :3] @ handle + R[:3, 3]
            assert moved[0] > handle[0] + 0.05  # the handle comes towards the person on +x (pulled open)
            world = door.pose @ R
            corners = np.array([[x, y, 0.0, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]) @ world.T
            q = corners[[0, 1, 3, 2], :2]  # the swung leaf's footprint (convex quad)
            # it stays within the room (the part near the hinge inside the wall opening) ...
            assert (q[:, 0] > -T - 1e-6).all() and (q[:, 0] < W + T + 1e-6).all()
            assert (q[:, 1] > -T - 1e-6).all() and (q[:, 1] < D + T + 1e-6).all()
            # ... and never meets a piece of furniture: the room keeps the door's clear zone free
            for name, fp in fps.items():
                assert not quads_overlap(q, fp), (sc.name, name, a)


def test_drawer_slides_out_of_its_cabinet():
    sc = next(s for s in (make_room(k) for k in range(10)) if any(o.category == "drawer" for o in s.objects.values()))
    dr = next(o for o in sc.objects.values() if o.category == "drawer")
    cab = sc.object(dr.meta["parent"])
    front = cab.mesh.bounds[1, 0]
    h_closed = _local(cab, _world(dr, dr.meta["handle"]))
    assert h_closed[0] > front - 1e-6
    opened = dr.pose.copy()
    opened[:3, 3] += dr.pose[:3, :3] @ dr.axis * dr.meta["max_travel"]
    h_open = _local(cab, opened[:3, :3] @ np.asarray(dr.meta["handle"]) + opened[:3, 3])
    np.testing.assert_allclose(h_open - h_closed, [dr.meta["max_travel"], 0, 0], atol=1e-9)
    # the opened drawer's handle is still short of the approach point
    a = np.asarray(cab.meta["approach"])
    assert h_open[0] < a[0] - 0.1


def test_no_interpenetration():
    for s in range(4):
        sc = make_room(s)
        meshes = {k: o.world_mesh() for k, o in sc.objects.items()} | dict(sc.static)
        for a, ma in meshes.items():
            pts = []
            for part in ma.split(only_watertight=False):
                p, _ = trimesh.sample.sample_surface(part, 100, seed=1)
                pts.append(part.centroid + (p - part.centroid) * 0.97)  # just inside convex parts
            pts = np.concatenate(pts)
            for b, mb in meshes.items():
                if a == b or np.any(mb.bounds[0] > pts.max(0)) or np.any(mb.bounds[1] < pts.min(0)):
                    continue
                inside = np.zeros(len(pts), dtype=bool)
                for part in mb.split(only_watertight=False):
                    inside |= part.contains(pts)
                assert not inside.any(), (sc.name, a, "inside", b)


def test_explicit_furniture_and_bad_inputs():
    sc = make_room(1, size=(6.0, 5.0), furniture=["desk", "bed", "cabinet", "stool", "cup", "book"])
    cats = Counter(o.category for o in sc.objects.values())
    assert cats["desk"] == 1 and cats["bed"] == 1 and cats["cabinet"] == 1 and cats["stool"] == 1
    assert cats["chair"] == 1 and cats["cup"] == 1 and cats["book"] == 1 and cats["sofa"] == 0
    assert sc.meta["size"] == [6.0, 5.0]
    with pytest.raises(ValueError, match="unknown"):
        make_room(0, furniture=["throne"])
    with pytest.raises(ValueError, match="come with a desk"):
        make_room(0, furniture=["keyboard"])
    with pytest.raises(ValueError, match="need a surface"):
        make_room(0, furniture=["chair", "cup"])
    with pytest.raises(ValueError, match="size"):
        make_room(0, size=(1.0, 5.0))
    with pytest.raises(ValueError, match="could not place"):
        make_room(0, size=(2.6, 2.6), furniture=["bed", "bed", "sofa", "desk"])
    with pytest.raises(ValueError, match="size"):
        make_room(0, size=5.0)
    empty = make_room(2, furniture=[])
    assert [o.category for o in empty.objects.values()] == ["door"]
    with pytest.raises(ValueError, match="seed"):
        make_room(1.5)


def test_with_occupancy_walkability_and_io(tmp_path):
    """Cross-check with the scene tools: every approach point is walkable on the ray-cast
    occupancy grid (body radius 0.12 m) and a path leads there from the door; the room survives
    a save/load round trip with watertight meshes and identical meta."""
    from trumans.scenes.io import load_scene, save_scene
    from trumans.scenes.occupancy import scene_occupancy
    from trumans.scenes.walkability import plan_path, walkable_map

    for s in (0, 1):
        sc = make_room(s)
        wm = walkable_map(scene_occupancy(sc, voxel=0.05), body_radius=0.12)
        aps = approach_points(sc)
        door = aps[sc.meta["door"]]
        for name, p in aps.items():
            assert wm.query(p), (sc.name, name)
            path = plan_path(wm, door, p)
            np.testing.assert_allclose(path[-1], p)
        save_scene(sc, tmp_path / sc.name)
        back = load_scene(tmp_path / sc.name)
        assert set(back.objects) == set(sc.objects) and back.meta == sc.meta
        for k, o in back.objects.items():
            assert o.mesh.is_watertight and o.meta == sc.objects[k].meta and o.dof == sc.objects[k].dof
