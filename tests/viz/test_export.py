"""trumans.viz.export: npz / bvh / gif / png / glb outputs that read back, and their errors."""
from __future__ import annotations

import importlib.util
import json
import struct

import imageio.v2 as imageio
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from trumans.viz.export import FORMATS, export, export_paths, skeleton_motion
from trumans.viz.glb import BONE_RADIUS, Z_UP_TO_Y_UP
from trumans.scenes.io import save_scene
from trumans.scenes.scene import Scene, SceneObject
from trumans.importers.bvh import import_bvh
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d
from trumans.sequence import ObjectTrack, Sequence, load_sequence
from trumans.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS, children, forward_kinematics, rest_offsets

FPS = 10.0


def _motion(T: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth random local rotations (up to ~0.5 rad), a walking root and slightly scaled offsets."""
    rng = np.random.default_rng(seed)
    a0, a1 = rng.normal(0, 0.25, (2, NUM_JOINTS, 3))
    w = np.linspace(0, 1, T)[:, None, None]
    rot = axis_angle_to_matrix((1 - w) * a0 + w * a1)
    rot[:, 0] = Rotation.from_euler("z", np.linspace(0, 2.5, T)[:, None]).as_matrix()  # turning more than 90 deg
    root = np.stack([np.linspace(0, 1.2, T), np.linspace(0, 0.4, T), np.full(T, 0.95)], -1)
    return rot, root, rest_offsets(1.04)


def _scene_and_seq(T: int = 12) -> tuple[Sequence, Scene]:
    rot, root, off = _motion(T)
    P, _ = forward_kinematics(rot, root, off)
    box = trimesh.creation.box([0.2, 0.3, 0.1])
    pose = np.tile(np.eye(4), (T, 1, 1))
    pose[:, :3, :3] = Rotation.from_euler("z", np.linspace(0, 3.0, T)[:, None]).as_matrix()
    pose[:, :3, 3] = np.stack([np.full(T, 2.0), np.linspace(0, 1, T), np.full(T, 0.8)], -1)
    table = SceneObject("table", "table", trimesh.creation.box([1.0, 0.6, 0.7]),
                        pose=trimesh.transformations.translation_matrix([2.0, 0.0, 0.35]))
    sc = Scene("toy", static={"floor": trimesh.creation.box([4.0, 4.0, 0.02])},
               objects={"table": table, "box": SceneObject("box", "box", box, dof="free", dynamic=True)})
    seq = Sequence(joints=P.astype(np.float32), fps=FPS, rotations=matrix_to_6d(rot).astype(np.float32),
                   root_pos=root.astype(np.float32), objects={"box": ObjectTrack(pose.astype(np.float32), "box")},
                   extra={"offsets": off.astype(np.float32)})
    return seq, sc


def _read_glb(path) -> tuple[dict, bytes]:
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    jlen, jtype = struct.unpack_from("<I4s", data, 12)
    assert jtype == b"JSON" and jlen % 4 == 0
    gltf = json.loads(data[20:20 + jlen])
    blen, btype = struct.unpack_from("<I4s", data, 20 + jlen)
    assert btype == b"BIN\0" and blen % 4 == 0 and 28 + jlen + blen == len(data)
    assert gltf["buffers"][0]["byteLength"] <= blen
    return gltf, data[28 + jlen:28 + jlen + blen]


def _accessor(gltf: dict, bin_: bytes, i: int) -> np.ndarray:
    acc = gltf["accessors"][i]
    view = gltf["bufferViews"][acc["bufferView"]]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16}[acc["componentType"]]
    a = np.frombuffer(bin_, dtype, acc["count"] * width, view["byteOffset"] + acc.get("byteOffset", 0))
    return a.reshape(acc["count"], width) if width > 1 else a


def _node_matrices(gltf: dict, bin_: bytes, frame: int) -> dict[int, np.ndarray]:
    """World matrices of every node at ``frame``: rest TRS overridden by the animation channels."""
    trs = {i: {"translation": np.array(n.get("translation", [0.0, 0, 0])),
               "rotation": np.array(n.get("rotation", [0.0, 0, 0, 1])),
               "scale": np.array(n.get("scale", [1.0, 1, 1]))} for i, n in enumerate(gltf["nodes"])}
    anim = gltf["animations"][0]
    for ch in anim["channels"]:
        out = _accessor(gltf, bin_, anim["samplers"][ch["sampler"]]["output"])
        trs[ch["target"]["node"]][ch["target"]["path"]] = out[frame].astype(np.float64)
    parent = {c: i for i, n in enumerate(gltf["nodes"]) for c in n.get("children", [])}
    world: dict[int, np.ndarray] = {}

    def get(i: int) -> np.ndarray:
        if i not in world:
            M = np.eye(4)
            M[:3, :3] = Rotation.from_quat(trs[i]["rotation"]).as_matrix() * trs[i]["scale"]
            M[:3, 3] = trs[i]["translation"]
            world[i] = (get(parent[i]) if i in parent else np.eye(4)) @ M
        return world[i]

    for i in range(len(gltf["nodes"])):
        get(i)
    return world


def test_glb_animation_reproduces_joints_and_objects(tmp_path):
    seq, sc = _scene_and_seq()
    T = seq.num_frames
    out = export(seq, tmp_path / "run", {"glb"}, sc)
    assert out == {"glb": tmp_path / "run.glb"}
    gltf, bin_ = _read_glb(out["glb"])
    names = [n.get("name") for n in gltf["nodes"]]
    jnode = [names.index(n) for n in JOINT_NAMES]
    for j in range(1, NUM_JOINTS):  # the skeleton's hierarchy
        assert jnode[j] in gltf["nodes"][jnode[PARENTS[j]]]["children"]
    assert len(gltf["animations"]) == 1
    anim = gltf["animations"][0]
    targets = {(ch["target"]["node"], ch["target"]["path"]) for ch in anim["channels"]}
    assert {(n, "rotation") for n in jnode} <= targets and (jnode[0], "translation") in targets
    box = names.index("box")
    assert {(box, "translation"), (box, "rotation")} <= targets
    for s in anim["samplers"]:
        assert s["interpolation"] == "LINEAR"
        t = _accessor(gltf, bin_, s["input"])
        acc = gltf["accessors"][s["input"]]
        assert len(t) == T and np.all(np.diff(t) > 0)
        assert acc["min"] == [0.0] and acc["max"][0] == pytest.approx((T - 1) / FPS)
    for m in gltf["meshes"]:
        acc = gltf["accessors"][m["primitives"][0]["attributes"]["POSITION"]]
        v = _accessor(gltf, bin_, m["primitives"][0]["attributes"]["POSITION"])
        np.testing.assert_allclose(acc["min"], v.min(0)), np.testing.assert_allclose(acc["max"], v.max(0))
    y_from_z = Rotation.from_quat(Z_UP_TO_Y_UP).as_matrix()
    np.testing.assert_allclose(y_from_z @ [1.0, 2.0, 3.0], [1.0, 3.0, -2.0], atol=1e-12)  # (x, y, z) -> (x, z, -y)
    for f in (0, T // 2, T - 1):
        world = _node_matrices(gltf, bin_, f)
        P = np.stack([world[n][:3, 3] for n in jnode]) @ y_from_z  # back to z-up
        assert np.abs(P - seq.joints[f]).max() < 1e-3
        pose_back = np.eye(4)
        pose_back[:3] = y_from_z.T @ world[box][:3]
        np.testing.assert_allclose(pose_back, seq.objects["box"].pose[f], atol=1e-5)
    # one skinned body: its joints are the skeleton's nodes, and every limb capsule, skinned at the last
    # frame (joint world matrix @ inverse bind matrix, glTF 2.0 §3.7.3), hugs the bone to a child joint
    (skin,) = gltf["skins"]
    assert skin["joints"] == jnode and skin["skeleton"] == jnode[0]
    (body,) = [i for i, n in enumerate(gltf["nodes"]) if n.get("skin") == 0]
    assert body in gltf["scenes"][0]["nodes"]  # a root node (its own transform is unused)
    prim = gltf["meshes"][gltf["nodes"][body]["mesh"]]["primitives"][0]
    v = _accessor(gltf, bin_, prim["attributes"]["POSITION"]).astype(np.float64)
    owner = _accessor(gltf, bin_, prim["attributes"]["JOINTS_0"])[:, 0].astype(int)
    assert (_accessor(gltf, bin_, prim["attributes"]["WEIGHTS_0"]) == [1, 0, 0, 0]).all()
    ibm = _accessor(gltf, bin_, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1).astype(np.float64)
    world, P = _node_matrices(gltf, bin_, T - 1), seq.joints[T - 1].astype(np.float64)
    for j in set(owner.tolist()) - {JOINT_NAMES.index("head")}:
        M = world[jnode[j]] @ ibm[j]
        vj = (v[owner == j] @ M[:3, :3].T + M[:3, 3]) @ y_from_z
        dist = []
        for c in children(j):
            a, b = P[j], P[c]
            u = np.clip((vj - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
            dist.append(np.linalg.norm(vj - (a + u[:, None] * (b - a)), axis=-1) - BONE_RADIUS[JOINT_NAMES[c]])
        assert np.min(dist, axis=0).max() < 2e-3, JOINT_NAMES[j]
    table = _node_matrices(gltf, bin_, 0)[names.index("table")]
    np.testing.assert_allclose(y_from_z.T @ table[:3, 3], [2.0, 0.0, 0.35], atol=1e-6)  # static object at its pose


def test_glb_loads_in_trimesh_with_the_body_at_frame0(tmp_path):
    seq, sc = _scene_and_seq()
    path = export(seq, tmp_path / "run", "glb", sc)["glb"]
    scene = trimesh.load(path)
    assert isinstance(scene, trimesh.Scene)
    geoms = set(scene.geometry)
    assert {"floor", "table", "box", "body"} <= geoms
    dumped = scene.to_geometry() if hasattr(scene, "to_geometry") else scene.dump(concatenate=True)
    # the rest-state (frame 0) body lies around the frame-0 joints, in glTF's y-up frame
    y_from_z = Rotation.from_quat(Z_UP_TO_Y_UP).as_matrix()
    j0 = seq.joints[0] @ y_from_z.T
    lo, hi = dumped.bounds
    assert np.all(lo <= j0.min(0) + 1e-6) and np.all(hi >= j0.max(0) - 1e-6)


def test_bvh_from_joints_only_reads_back(tmp_path):
    seq, _ = _scene_and_seq(T=8)
    joints_only = Sequence(joints=seq.joints, fps=seq.fps)  # no rotations: fitted on export
    path = export(joints_only, tmp_path / "walk", {"bvh"})["bvh"]
    back = import_bvh(path)
    assert back.fps == pytest.approx(FPS) and back.num_frames == seq.num_frames
    assert np.abs(back.joints - seq.joints).max() < 0.005


def test_stored_rotations_are_used_when_consistent_else_fitted():
    seq, _ = _scene_and_seq(T=6)
    rot, root, off = skeleton_motion(seq)
    np.testing.assert_allclose(off, seq.extra["offsets"], atol=1e-6)
    np.testing.assert_allclose(root, seq.root_pos, atol=1e-6)
    bad = Sequence(joints=seq.joints, fps=seq.fps, rotations=np.tile(matrix_to_6d(np.eye(3)), (6, NUM_JOINTS, 1)),
                   root_pos=seq.root_pos)  # identity rotations do not give these joints: refit
    rot, root, off = skeleton_motion(bad)
    P, _ = forward_kinematics(rot, root, off)
    assert np.abs(P - seq.joints).max() < 0.005


def test_npz_gif_png_round_trip(tmp_path):
    seq, sc = _scene_and_seq(T=6)
    out = export(seq, tmp_path / "sub" / "run", {"npz", "gif", "png"}, sc, stride=2)
    assert set(out) == {"npz", "gif", "png"} and out["png"].name == "run_top.png"
    back = load_sequence(out["npz"])
    np.testing.assert_array_equal(back.joints, seq.joints)
    np.testing.assert_array_equal(back.objects["box"].pose, seq.objects["box"].pose)
    assert len(imageio.mimread(out["gif"])) == 3  # frames 0, 2, 4
    assert imageio.imread(out["png"]).ndim == 3
    assert not list((tmp_path / "sub").glob(".*tmp"))  # atomic writes leave no temp files


def test_scene_folder_and_mp4(tmp_path):
    seq, sc = _scene_and_seq(T=4)
    save_scene(sc, tmp_path / "room")
    if importlib.util.find_spec("imageio_ffmpeg") is None:
        with pytest.raises(ValueError, match="ffmpeg"):
            export(seq, tmp_path / "run", {"mp4", "npz"}, tmp_path / "room")
        assert not (tmp_path / "run.npz").exists()  # refused before writing anything
    else:
        assert export(seq, tmp_path / "run", {"mp4"}, tmp_path / "room")["mp4"].stat().st_size > 0
    gltf, _ = _read_glb(export(seq, tmp_path / "run", {"glb"}, tmp_path / "room")["glb"])
    assert {"floor", "table", "box"} <= {n.get("name") for n in gltf["nodes"]}


def test_bad_requests_fail_clearly(tmp_path):
    seq, _ = _scene_and_seq(T=3)
    with pytest.raises(ValueError, match=r"unknown export format.*'fbx'"):
        export(seq, tmp_path / "x", {"npz", "fbx"})
    with pytest.raises(ValueError, match="no export format"):
        export(seq, tmp_path / "x", set())
    with pytest.raises(ValueError, match="without a format suffix"):
        export_paths(tmp_path / "x.npz", {"npz"})
    with pytest.raises(ValueError, match=r"no output path given for format\(s\) \['bvh'\]"):
        export_paths({"npz": tmp_path / "a.npz"}, {"npz", "bvh"})
    with pytest.raises(ValueError, match=r"gif output must end in \.gif"):
        export_paths({"gif": tmp_path / "a.png"}, {"gif"})
    with pytest.raises(FileNotFoundError, match="not a scene folder"):
        export(seq, tmp_path / "x", {"npz"}, tmp_path / "nowhere")
    assert not list(tmp_path.iterdir())
    assert set(FORMATS) == {"npz", "bvh", "gif", "mp4", "png", "glb"}


def test_bvh_and_glb_of_one_sequence_share_one_world_frame(tmp_path):
    """One y-up frame for every export: the BVH's joints (file units, file axes) lie where the GLB's
    joints lie (glTF's y-up world), within 1 mm, and both are the npz turned by ``Y_UP_TO_Z_UP.T``."""
    from trumans.bvh import read_bvh
    from trumans.rotations import Y_UP_TO_Z_UP

    seq, sc = _scene_and_seq()
    out = export(seq, tmp_path / "run", {"glb", "bvh"}, sc)
    gltf, bin_ = _read_glb(out["glb"])
    names = [n.get("name") for n in gltf["nodes"]]
    jnode = [names.index(n) for n in JOINT_NAMES]
    bvh = read_bvh(out["bvh"])
    P_bvh, _ = bvh.forward_kinematics()
    P_bvh = P_bvh[:, [bvh.names.index(n) for n in JOINT_NAMES]]
    for f in (0, seq.num_frames - 1):
        world = _node_matrices(gltf, bin_, f)
        P_glb = np.stack([world[n][:3, 3] for n in jnode])
        assert np.abs(P_glb - P_bvh[f]).max() < 1e-3
        np.testing.assert_allclose(P_bvh[f], seq.joints[f] @ Y_UP_TO_Z_UP, atol=1e-3)  # (x, y, z) -> (x, z, -y)
