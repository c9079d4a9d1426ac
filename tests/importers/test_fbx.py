"""trumans.importers.fbx: the node reader (ASCII / binary), transforms, curves and the skeleton import."""
import struct
import zlib

import numpy as np
import pytest

from trumans.importers.bvh import import_bvh
from trumans.importers.fbx import FBX_TICKS, import_fbx, joint_positions, read_fbx, up_axis_matrix
from trumans.importers.fbx_nodes import parse_ascii, parse_binary, read_fbx_nodes
from trumans.importers.joint_maps import detect_skeleton, floor_height, place_pelvis
from trumans.skeleton import JOINT_INDEX, REST_JOINTS

from helpers import TEST_DATA

CMU_FBX = TEST_DATA / "cmu_13_10_daz_first12keys.fbx"
CMU_BVH = TEST_DATA / "cmu_13_10_daz_first56.bvh"
ANIM = {(v, enc): TEST_DATA / f"ufbx_maya_transform_animation_{v}_{enc}.fbx" for v in (6100, 7500)
        for enc in ("ascii", "binary")}


@pytest.fixture(scope="module")
def cmu_fbx():
    return import_fbx(CMU_FBX, refine_steps=0)


# ------------------------------------------------------------------------------------ node reader

@pytest.mark.parametrize("key", list(ANIM))
def test_reads_every_encoding_and_version(key):
    nodes, version, binary = read_fbx_nodes(ANIM[key])
    assert version == key[0] and binary == (key[1] == "binary")
    names = [n.name for n in nodes]
    assert {"Objects", "Connections", "Takes"} <= set(names)


def test_binary_and_ascii_give_the_same_animation():
    ref = None
    t = np.array([1, 7, 14, 20, 24]) / 24.0
    for key, path in ANIM.items():
        scene = read_fbx(path)
        assert scene.names == ["pCube1"] and scene.up_axis == 1
        W = scene.world_matrices(t)
        if ref is None:
            ref = W
        np.testing.assert_allclose(W, ref, atol=1e-6, err_msg=str(key))


def test_curves_hit_their_keys():
    # Maya keys pCube1 at frames 1, 14, 24 (24 fps): T = 0, (1, 2, 3), (-1, -2, -3); R = 0, (10, 20, 30) deg
    for path in ANIM.values():
        scene = read_fbx(path)
        m = scene.models[0]
        kt, kv, _ = m.curves[("Lcl Translation", 1)]
        np.testing.assert_allclose(kt * 24, [1, 14, 24], atol=1e-9)
        np.testing.assert_allclose(kv, [0, 2, -2])
        L = scene.local_matrices(np.array([14 / 24]))[0, 0]
        np.testing.assert_allclose(L[:3, 3], [1, 2, 3], atol=1e-6)
        R = L[:3, :3] / np.linalg.norm(L[:3, :3], axis=0)  # scale removed
        from scipy.spatial.transform import Rotation
        np.testing.assert_allclose(Rotation.from_matrix(R).as_euler("xyz", degrees=True), [10, 20, 30], atol=1e-4)


def test_rotation_orders_match_maya():
    """World matrices of six meshes with RotationOrder XYZ..ZYX, applied to their vertices, give
    Maya's own world-space vertices (the .obj ufbx checks against)."""
    path = TEST_DATA / "ufbx_maya_rotation_order_7500_binary.fbx"
    scene = read_fbx(path)
    assert sorted(m.rotation_order for m in scene.models) == [0, 1, 2, 3, 4, 5]
    W = scene.world_matrices(np.zeros(1))[0]
    nodes, _, _ = read_fbx_nodes(path)
    top = {n.name: n for n in nodes}
    geo = {n.props[0]: n.find("Vertices").props[0].reshape(-1, 3) for n in top["Objects"].find_all("Geometry")}
    model_name = {n.props[0]: n.props[1].split("::")[1] for n in top["Objects"].find_all("Model")}
    owner = {c.props[1]: c.props[2] for c in top["Connections"].children if c.props[1] in geo}
    verts, groups, cur = [], {}, None
    for line in (TEST_DATA / "ufbx_maya_rotation_order.obj").read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:]])
        elif line.startswith("g "):
            cur = line.split()[1]
        elif line.startswith("f ") and cur:
            groups.setdefault(cur, set()).update(int(t.split("/")[0]) - 1 for t in line.split()[1:])
    verts = np.array(verts)
    assert len(geo) == 6
    for gid, v in geo.items():
        name = model_name[owner[gid]]
        k = scene.index(name)
        world = v @ W[k, :3, :3].T + W[k, :3, 3]
        truth = verts[sorted(groups[name])]
        np.testing.assert_allclose(np.sort(world, 0), np.sort(truth, 0), atol=1e-5, err_msg=name)


def test_binary_arrays_raw_and_zlib():
    """A hand-made binary FBX 7.5 (64-bit records): raw and zlib-compressed arrays, scalars, strings."""
    def prop_array(code, arr, compress):
        raw = arr.tobytes()
        data = zlib.compress(raw) if compress else raw
        return code + struct.pack("<III", len(arr), int(compress), len(data)) + data

    def node(name, props, children=b""):
        body = b"".join(props)
        head_len = 25 + len(name)  # end, count, length (uint64 each), name length (uint8), name
        end_pad = 25 if children else 0
        return (lambda start: struct.pack("<QQQB", start + head_len + len(body) + len(children) + end_pad,
                                          len(props), len(body), len(name)) + name + body + children
                + (b"\0" * 25 if children else b""))

    vals = np.arange(10, dtype=np.float64) * 0.5
    header = b"Kaydara FBX Binary  \x00\x1a\x00" + struct.pack("<I", 7500)
    start = len(header)
    leaf_a = node(b"A", [prop_array(b"d", vals, True), b"I" + struct.pack("<i", -7)])
    leaf_b = node(b"B", [prop_array(b"l", np.array([3, 1 << 40], np.int64), False),
                         b"S" + struct.pack("<I", 10) + b"hip\x00\x01Model"])
    a = leaf_a(start)
    b = leaf_b(start + len(a))
    data = header + a + b + b"\0" * 25
    nodes, version = parse_binary(data)
    assert version == 7500 and [n.name for n in nodes] == ["A", "B"]
    np.testing.assert_array_equal(nodes[0].props[0], vals)
    assert nodes[0].props[1] == -7
    np.testing.assert_array_equal(nodes[1].props[0], [3, 1 << 40])
    assert nodes[1].props[1] == "Model::hip"  # "name\0\1Class" -> "Class::name"


def test_ascii_values_and_arrays():
    nodes = parse_ascii('; comment\nA: 1, 2.5, "x, y", L {\n\tKeyTime: *3 {\n\t\ta: 0,1924423250,\n3848846500\n\t}\n'
                        '\tKey: \n\t\t0,1.5,L,\n\t\t1924423250,2.5,L\n}\n')
    a = nodes[0]
    assert a.props == [1, 2.5, "x, y", "L"]
    np.testing.assert_array_equal(a.find("KeyTime").props[0], [0, 1924423250, 3848846500])
    assert a.find("Key").props == [0, 1.5, "L", 1924423250, 2.5, "L"]


# ------------------------------------------------------------------------------------ CMU skeleton

def test_cmu_fbx_scene():
    scene = read_fbx(CMU_FBX)
    assert scene.version == 6100 and not scene.binary and scene.up_axis == 1 and scene.unit_cm == 1.0
    assert scene.key_fps() == 24.0
    t0, t1 = scene.time_range()
    assert t0 == 0.0 and t1 == pytest.approx(11 * 1924423250 / FBX_TICKS)
    assert {"hip", "lThigh", "lShin", "lFoot", "lCollar", "lShldr", "lForeArm", "lHand"} <= set(scene.names)
    names, P = joint_positions(scene, np.arange(12) / 24)
    assert "lFoot_end" in names and "rFoot_end" in names  # LimbLength ends of leaf bones
    assert detect_skeleton(names) == "daz"
    # thigh and shin lengths of the CMU subject (FBX units are cm): 36.8 and 45.4
    i = {n: k for k, n in enumerate(names)}
    np.testing.assert_allclose(np.linalg.norm(P[:, i["lShin"]] - P[:, i["lThigh"]], axis=-1), 0.368, atol=0.003)
    np.testing.assert_allclose(np.linalg.norm(P[:, i["lFoot"]] - P[:, i["lShin"]], axis=-1), 0.454, atol=0.003)


def test_cmu_fbx_matches_the_bvh_of_the_same_take(cmu_fbx):
    """The FBX (24 fps keys) and the Daz BVH (120 fps) of CMU 13_10: the pelvis paths agree within 2 cm."""
    bvh = import_bvh(CMU_BVH, fps=24, refine_steps=0)
    assert cmu_fbx.fps == 24.0 and cmu_fbx.num_frames == 12
    n = min(cmu_fbx.num_frames, bvh.num_frames)
    assert n >= 11
    d = np.linalg.norm(cmu_fbx.joints[:n, 0] - bvh.joints[:n, 0], axis=-1)
    assert d.max() < 0.02
    # every joint, not only the pelvis (same skeleton, same map)
    assert np.abs(cmu_fbx.joints[:n] - bvh.joints[:n]).max() < 0.02


def test_cmu_fbx_stands_on_the_floor(cmu_fbx):
    assert abs(floor_height(cmu_fbx.joints)) < 0.05
    pelvis_z = cmu_fbx.joints[:, JOINT_INDEX["pelvis"], 2]
    assert 0.8 < pelvis_z.mean() < 1.05  # standing
    head = cmu_fbx.joints[:, JOINT_INDEX["head"], 2]
    assert (head > pelvis_z + 0.4).all()  # upright, z up
    assert cmu_fbx.rotations.shape == (12, 24, 6)


def test_cmu_fbx_resampled_to_30(tmp_path):
    seq = import_fbx(CMU_FBX, fps=30, refine_steps=0)
    assert seq.fps == 30 and seq.num_frames == 14  # 11/24 s at 30 fps


def test_up_axis_matrix():
    np.testing.assert_allclose(up_axis_matrix(1) @ [0, 1, 0], [0, 0, 1])
    np.testing.assert_allclose(up_axis_matrix(0) @ [1, 0, 0], [0, 0, 1])
    np.testing.assert_allclose(up_axis_matrix(2), np.eye(3))
    for a in (0, 1, 2):
        for s in (1, -1):
            assert np.linalg.det(up_axis_matrix(a, s)) == pytest.approx(1.0)
    np.testing.assert_allclose(up_axis_matrix(1, -1) @ [0, -1, 0], [0, 0, 1])
    with pytest.raises(ValueError, match="UpAxis must be 0, 1 or 2"):
        up_axis_matrix(3)


# ------------------------------------------------------------------------------------ bad input

def test_bad_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_fbx(tmp_path / "none.fbx")
    with pytest.raises(ValueError, match="is a folder, not a file"):
        read_fbx(tmp_path)
    (tmp_path / "junk.fbx").write_text("hello: 1\n")
    with pytest.raises(ValueError, match="not an FBX file"):
        read_fbx(tmp_path / "junk.fbx")
    data = ANIM[(7500, "binary")].read_bytes()
    (tmp_path / "cut.fbx").write_bytes(data[:len(data) // 2])
    with pytest.raises(ValueError, match="cut.fbx.*truncated"):
        read_fbx(tmp_path / "cut.fbx")
    text = CMU_FBX.read_text()
    (tmp_path / "open.fbx").write_text(text[:len(text) // 2])
    with pytest.raises(ValueError, match="open.fbx.*unclosed.*truncated"):
        read_fbx(tmp_path / "open.fbx")


def test_fbx_without_a_skeleton():
    with pytest.raises(ValueError, match=r"no skeleton.*pCube1 \(Mesh\)"):
        import_fbx(ANIM[(7500, "ascii")])


def test_bad_arguments():
    with pytest.raises(ValueError, match="fps must be positive"):
        import_fbx(CMU_FBX, fps=0)
    with pytest.raises(ValueError, match="unknown skeleton style 'poser'"):
        import_fbx(CMU_FBX, skeleton="poser")
    with pytest.raises(ValueError, match="the skeleton is not 'cmu_mb'.*Hips"):
        import_fbx(CMU_FBX, skeleton="cmu_mb")


# ------------------------------------------------------------------------------------ CLI and floor

def test_cli_imports_fbx(tmp_path):
    import json

    from trumans.cli import main
    from trumans.sequence import load_sequence

    out = tmp_path / "ds"
    assert main(["data", "import", "--format", "fbx", str(CMU_FBX), "--out", str(out), "--fps", "30",
                 "--feet-on-floor"]) == 0
    index = json.loads((out / "index.json").read_text())
    # 12 keys at 24 fps less the Daz T-pose key (dropped before resampling): 10/24 s -> 13 frames at 30 fps
    assert index["counts"] == {"sequences": 1, "frames": 13} and index["fps"] == 30.0
    seq = load_sequence(out / "sequences" / "cmu_13_10_daz_first12keys.npz")
    assert abs(floor_height(seq.joints)) < 1e-3


def test_bvh_with_the_hip_height_in_its_root_offset(tmp_path):
    """A BVH whose root OFFSET holds the hip height while its position channels hold the rest
    imports under the floor: it is reported, and --feet-on-floor puts it back."""
    lines = CMU_BVH.read_text().splitlines()
    k = lines.index("MOTION")
    hip = 85.0
    lines[3] = f"  OFFSET 0 {hip} 0"
    rows = []
    for row in lines[k + 3:]:
        v = row.split()
        v[1] = f"{float(v[1]) - hip:.5f}"  # Yposition now relative to the offset
        rows.append(" ".join(v))
    p = tmp_path / "offset_root.bvh"
    p.write_text("\n".join(lines[:k + 3] + rows) + "\n")
    with pytest.warns(UserWarning, match=r"feet are 0\.8\d m under the floor.*--feet-on-floor"):
        low = import_bvh(p, refine_steps=0)
    fixed = import_bvh(p, refine_steps=0, feet_on_floor=True)
    good = import_bvh(CMU_BVH, refine_steps=0)
    assert abs(floor_height(fixed.joints)) < 1e-4
    assert float(fixed.extra["floor_shift_m"]) == pytest.approx(0.85, abs=0.01)
    np.testing.assert_allclose(fixed.joints, good.joints - [0, 0, floor_height(good.joints)], atol=1e-4)
    np.testing.assert_allclose(fixed.root_pos[:, :2], low.root_pos[:, :2], atol=1e-6)


def _hips_to_pelvis_up(P):
    """Height of the pelvis joint over the hip joints' midpoint, along the hips -> spine1 direction (T,)."""
    J = JOINT_INDEX
    mid = 0.5 * (P[:, J["left_hip"]] + P[:, J["right_hip"]])
    up = P[:, J["spine1"]] - mid
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    return np.einsum("ti,ti->t", P[:, J["pelvis"]] - mid, up)


def test_place_pelvis_leaves_our_convention_alone():
    P = np.repeat(REST_JOINTS[None], 5, 0) + np.array([1.0, 2.0, 0.0])
    np.testing.assert_array_equal(place_pelvis(P), P)


def test_place_pelvis_lifts_a_hip_level_root_into_the_pelvis():
    """A root at the hips' midpoint (CMU's "hip") goes where the rest pose has our pelvis relative to
    the hips and spine1, in a turned and tilted body too; every other joint stays."""
    from scipy.spatial.transform import Rotation
    J = JOINT_INDEX
    R = Rotation.from_euler("zx", [[t, 0.3 * np.sin(t)] for t in np.linspace(0, 3, 7)])
    P = np.stack([r.apply(REST_JOINTS) for r in R]) + np.array([0.5, -1.0, 0.2])
    want = P[:, J["pelvis"]].copy()
    P[:, J["pelvis"]] = 0.5 * (P[:, J["left_hip"]] + P[:, J["right_hip"]])
    out = place_pelvis(P)
    np.testing.assert_allclose(out[:, J["pelvis"]], want, atol=1e-9)
    np.testing.assert_array_equal(np.delete(out, J["pelvis"], 1), np.delete(P, J["pelvis"], 1))
    assert _hips_to_pelvis_up(out).min() > 0.05


def test_cmu_pelvis_sits_above_the_hips_like_ours(cmu_fbx):
    rest = _hips_to_pelvis_up(REST_JOINTS[None])[0]
    np.testing.assert_allclose(_hips_to_pelvis_up(cmu_fbx.joints), rest, atol=0.02)


def test_binary_array_inflation_bomb_is_refused_before_inflating():
    """A zlib array declaring far more values than its stored bytes can hold (8 GiB from 1 KiB) or
    inflating past what it declares is refused; nothing larger than the declared size is inflated."""
    def one_node_file(n, enc, payload):
        prop = b"d" + struct.pack("<III", n, enc, len(payload)) + payload
        header = b"Kaydara FBX Binary  \x00\x1a\x00" + struct.pack("<I", 7500)
        head_len = 25 + 1
        rec = struct.pack("<QQQB", len(header) + head_len + len(prop), 1, len(prop), 1) + b"A" + prop
        return header + rec + b"\0" * 25

    small = zlib.compress(b"\0" * 80)
    with pytest.raises(ValueError, match="more than zlib can hold"):
        parse_binary(one_node_file(1 << 30, 1, small))  # 8 GiB of float64 declared
    nodes, _ = parse_binary(one_node_file(10, 1, small))
    np.testing.assert_array_equal(nodes[0].props[0], np.zeros(10))
    with pytest.raises(ValueError, match="holds 80 of its 160 bytes"):
        parse_binary(one_node_file(20, 1, small))
    with pytest.raises(ValueError, match="does not inflate"):
        parse_binary(one_node_file(10, 1, b"not zlib data at all"))
