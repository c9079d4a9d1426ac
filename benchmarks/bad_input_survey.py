"""Survey of bad inputs over the `trumans` commands (issue 13): run each case through
``trumans.cli.console_main`` in-process and count how it ends.

Outcomes: ``clean`` (exit 2, exactly one ``trumans: error:`` line that names what the case
requires, no traceback), ``unclear`` (the one channel, but the message does not name the problem),
``other`` (another prefix, no message, or exit 1 via SystemExit), ``bug-line`` (the one-line "this
is a bug" report of an unexpected exception), ``traceback`` (an exception escapes), ``silent``
(exit 0, or a wrong result, where the case must fail or behave otherwise; also a refused run that
leaves its --out behind), ``hang`` (no end within the case's timeout), ``ok`` (a case whose right
answer is to succeed, and it did). The fixture is a one-room procedural dataset (``--real-share 0``:
no mocap takes, a few seconds to build). Usage::

    python benchmarks/bad_input_survey.py [--work /tmp/survey] [--only PREFIX]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OMP_NUM_THREADS", "1")

from trumans.cli import console_main  # noqa: E402

BVH = ROOT / "tests" / "data" / "cmu_131_01_start_walk_stop_first480.bvh"


class Hang(BaseException):
    """The case's timeout (a BaseException, so the CLI's error channel cannot report it as a bug)."""


def _alarm(*_):
    raise Hang()


def call(argv: list[str], timeout: int = 60) -> tuple[int | str, str, str]:
    """(exit status or 'exception:<type>' / 'hang', stdout, stderr) of one in-process run."""
    out, err = io.StringIO(), io.StringIO()
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(timeout)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            rc: int | str = console_main([str(a) for a in argv])
    except Hang:
        rc = "hang"
    except SystemExit as e:
        if isinstance(e.code, str):
            err.write(e.code + "\n")
            rc = 1
        else:
            rc = int(e.code or 0)
    except BaseException as e:  # noqa: BLE001 - counting what escapes is the point
        rc = f"exception:{type(e).__name__}"
        err.write(f"Traceback: {type(e).__name__}: {e}\n")
    finally:
        signal.alarm(0)
    return rc, out.getvalue(), err.getvalue()


def classify_error(rc, err: str, must: tuple[str, ...]) -> str:
    if rc == "hang":
        return "hang"
    if isinstance(rc, str):
        return "traceback"
    if rc == 0:
        return "silent"
    lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
    if "Traceback" in err:
        return "traceback"
    if len(lines) != 1 or rc != 2:
        if len(lines) == 1 and "this is a bug" in lines[0]:
            return "bug-line"
        return "other"
    if "this is a bug" in lines[0]:
        return "bug-line"
    low = lines[0].lower()
    if not all(m.lower() in low for m in must):
        return "unclear"
    return "clean"


# --------------------------------------------------------------------------- fixtures


def _synth(path: Path, seed: int = 0) -> None:
    rc, _, err = call(["data", "synth", "--out", path, "--hours", "0.01", "--rooms", "1", "--seed", seed,
                       "--workers", "1", "--real-share", "0", "--json"], timeout=300)
    if rc != 0:
        raise RuntimeError(f"fixture synth failed: {err[-2000:]}")


def _copy(src: Path, dst: Path) -> Path:
    if dst.exists():
        shutil.rmtree(dst)
    shutil.copytree(src, dst)
    return dst


def _edit_index(root: Path, fn) -> Path:
    idx = json.loads((root / "index.json").read_text())
    fn(idx)
    (root / "index.json").write_text(json.dumps(idx))
    return root


def _edit_scene(root: Path, fn) -> Path:
    scene_dir = next((root / "scenes").iterdir())
    doc = json.loads((scene_dir / "scene.json").read_text())
    fn(doc)
    (scene_dir / "scene.json").write_text(json.dumps(doc))
    return root


def _release(folder: Path, n: int = 40, scene_flag=None, joints=None) -> Path:
    from trumans.importers.trumans_release import Y_UP_TO_Z_UP
    from trumans.skeleton import REST_JOINTS

    folder.mkdir(parents=True, exist_ok=True)
    zup = REST_JOINTS[None] + np.linspace(0, 1, n)[:, None, None] * np.array([1.0, 0.5, 0.0])
    np.save(folder / "human_joints.npy", (zup @ Y_UP_TO_Z_UP).astype(np.float32) if joints is None else joints)
    if scene_flag is not None:
        np.save(folder / "scene_flag.npy", np.asarray(scene_flag))
        (folder / "Scene").mkdir(exist_ok=True)
        for k in range(2):
            np.save(folder / "Scene" / f"scene_{k}.npy", np.zeros((30, 10, 40), bool))
    return folder


def _zero_length(path: Path) -> Path:
    np.savez(path, joints=np.zeros((0, 24, 3), np.float32), fps=np.float32(30), scene=np.asarray(""))
    return path


def _snapshot(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in root.rglob("*") if p.is_file()}


# --------------------------------------------------------------------------- cases


def build_cases(w: Path, base: Path, aug_base: Path) -> list[tuple[str, object]]:
    """[(name, thunk -> outcome)]; each thunk builds its own inputs under ``w``."""
    cases: list[tuple[str, object]] = []

    def err(name: str, argv_fn, *must: str, timeout: int = 60) -> None:
        def thunk():
            argv = [str(a) for a in argv_fn()]
            out = Path(argv[argv.index("--out") + 1]) if "--out" in argv[:-1] else None
            watch = [] if out is None or not out.name else [p for p in (out, out.parent, out.with_suffix(".npz"))
                                                            if not p.exists()]  # `--out ""` / `.`: nothing to watch
            rc, _, e = call(argv, timeout)
            note = e.strip().splitlines()[-1:] if e.strip() else [f"rc={rc}"]
            outcome = classify_error(rc, e, must)
            left = [p for p in watch if p.exists()]
            if outcome == "clean" and left:  # a refused run leaves the disk as it was
                return "silent", [f"refused, but left {left[0]} behind"]
            return outcome, note
        cases.append((name, thunk))

    def custom(name: str, fn) -> None:
        cases.append((name, fn))

    seq0 = next((base / "sequences").glob("*.npz"))
    D = lambda tag: _copy(base, w / tag)  # noqa: E731

    # ---- data synth
    err("synth --hours 0", lambda: ["data", "synth", "--out", w / "s_h0", "--hours", "0"], "hours")
    err("synth --hours nan", lambda: ["data", "synth", "--out", w / "s_hn", "--hours", "nan"], "hours")
    err("synth --hours -1", lambda: ["data", "synth", "--out", w / "s_hm", "--hours", "-1"], "hours")
    err("synth --rooms 0", lambda: ["data", "synth", "--out", w / "s_r0", "--rooms", "0"], "rooms")
    err("synth --workers -1", lambda: ["data", "synth", "--out", w / "s_w", "--workers", "-1", "--hours", "0.01",
                                       "--rooms", "1"], "workers")
    err("synth --hours abc", lambda: ["data", "synth", "--out", w / "s_ha", "--hours", "abc"], "--hours")

    def synth_out_is_file():
        f = w / "afile"
        f.write_text("x")
        rc, _, e = call(["data", "synth", "--out", f, "--hours", "0.01", "--rooms", "1", "--workers", "1", "--real-share", "0"])
        return classify_error(rc, e, (str(f),)), e.strip().splitlines()[-1:]
    custom("synth --out is a file", synth_out_is_file)

    def synth_into_foreign(tag, make):
        def thunk():
            d = w / tag
            make(d)
            before = (d / "index.json").read_bytes()
            rc, _, e = call(["data", "synth", "--out", d, "--hours", "0.01", "--rooms", "1", "--workers", "1", "--real-share", "0"],
                            timeout=300)
            changed = (d / "index.json").read_bytes() != before
            if rc == 0 or changed:
                return "silent", [f"rc={rc} index changed={changed}"]
            return classify_error(rc, e, ("--overwrite",)), e.strip().splitlines()[-1:]
        return thunk
    custom("synth into another dataset (import)", synth_into_foreign(
        "s_foreign", lambda d: call(["data", "import", BVH, "--format", "bvh", "--out", d], timeout=300)))
    custom("synth into a synth of another seed", synth_into_foreign(
        "s_seed", lambda d: call(["data", "synth", "--out", d, "--hours", "0.01", "--rooms", "1", "--seed", "7",
                                  "--workers", "1", "--real-share", "0"], timeout=300)))

    # ---- data import
    err("import: release folder missing", lambda: ["data", "import", w / "nope", "--format", "trumans", "--out",
                                                   w / "i1"], "nope")
    err("import --format trumans two folders", lambda: ["data", "import", w, w, "--format", "trumans", "--out",
                                                        w / "i2"], "one")
    err("import --joint-map inline long JSON", lambda: [
        "data", "import", BVH, "--format", "bvh", "--out", w / "i3", "--joint-map",
        json.dumps({f"j{i:03d}": f"Bone{i:03d}" for i in range(40)})], "joint")
    def inline_map():  # valid inline JSON: must be accepted (it was read as a file name)
        rc, _, e = call(["data", "import", BVH, "--format", "bvh", "--out", w / "i3b", "--joint-map",
                         '{"pelvis": "Hips"}'])
        return ("ok" if rc == 0 else "unclear" if rc == 2 else classify_error(rc, e, ())), e.strip().splitlines()[-1:]
    custom("import --joint-map inline short JSON", inline_map)

    def bad_map_file(text):
        def fn():
            p = w / f"map{abs(hash(text)) % 1000}.json"
            p.write_text(text)
            return ["data", "import", BVH, "--format", "bvh", "--out", w / "i4", "--joint-map", p]
        return fn
    err("import --joint-map file bad JSON", bad_map_file("{pelvis: "), "joint")
    err("import --joint-map JSON list", bad_map_file('["pelvis"]'), "joint")
    err("import --joint-map unknown joint", bad_map_file('{"tail": "Hips"}'), "tail")
    err("import bvh missing", lambda: ["data", "import", w / "nope.bvh", "--format", "bvh", "--out", w / "i5"],
        "nope.bvh")

    def garbage_bvh():
        p = w / "garbage.bvh"
        p.write_bytes(b"\x00\x01garbage")
        return ["data", "import", p, "--format", "bvh", "--out", w / "i6"]
    err("import garbage bvh", garbage_bvh, "garbage.bvh")
    for val in ("0", "nan", "-1"):
        err(f"import --unit-scale {val}", lambda v=val: ["data", "import", BVH, "--format", "bvh", "--out", w / "i7",
                                                          "--unit-scale", v], "unit")
        err(f"import --fps {val}", lambda v=val: ["data", "import", BVH, "--format", "bvh", "--out", w / "i8",
                                                   "--fps", v], "fps")
    err("import --action-names missing", lambda: ["data", "import", _release(w / "rel_ok"), "--format", "trumans",
                                                  "--out", w / "i9", "--action-names", w / "nope.txt"], "nope.txt")

    def import_over_dataset():
        d = D("i_over")
        before = _snapshot(d)
        rc, _, e = call(["data", "import", BVH, "--format", "bvh", "--out", d])
        changed = _snapshot(d) != before
        if rc == 0 or changed:
            return "silent", [f"rc={rc} changed={changed}"]
        return classify_error(rc, e, ("--overwrite",)), e.strip().splitlines()[-1:]
    custom("import into an existing dataset", import_over_dataset)

    def import_zero_frames():
        rel = _release(w / "rel0", joints=np.zeros((0, 24, 3), np.float32))
        rc, _, e = call(["data", "import", rel, "--format", "trumans", "--out", w / "i10"])
        if rc == 0:
            return "silent", ["rc=0 (empty dataset written)"]
        return classify_error(rc, e, ("frame",)), e.strip().splitlines()[-1:]
    custom("import release with 0 frames", import_zero_frames)

    def import_flag_negative():
        rel = _release(w / "rel_neg", scene_flag=[-1] * 20 + [0] * 20)
        rc, _, e = call(["data", "import", rel, "--format", "trumans", "--out", w / "i11"])
        if rc == 0:
            return "silent", ["rc=0 (scene -1 mapped to the last scene)"]
        return classify_error(rc, e, ("scene_flag",)), e.strip().splitlines()[-1:]
    custom("import scene_flag -1", import_flag_negative)
    err("import human_joints wrong shape", lambda: ["data", "import", _release(
        w / "rel_shape", joints=np.zeros((5, 22, 3), np.float32)), "--format", "trumans", "--out", w / "i12"],
        "human_joints")

    def rel_pickled():
        rel = _release(w / "rel_pk", joints=np.array([{"a": 1}], dtype=object))
        return ["data", "import", rel, "--format", "trumans", "--out", w / "i13"]
    err("import human_joints pickled", rel_pickled, "human_joints")

    def rel_truncated():
        rel = _release(w / "rel_tr")
        b = (rel / "human_joints.npy").read_bytes()
        (rel / "human_joints.npy").write_bytes(b[: len(b) // 2])
        return ["data", "import", rel, "--format", "trumans", "--out", w / "i14"]
    err("import human_joints truncated", rel_truncated, "human_joints")

    def rel_names():
        rel = _release(w / "rel_names")
        np.save(rel / "object_flag.npy", np.zeros((40, 1), np.int64))
        np.save(rel / "object_mat.npy", np.tile(np.eye(4), (40, 1, 1, 1)))
        (rel / "object_names.json").write_text('{"a": 1}')
        return ["data", "import", rel, "--format", "trumans", "--out", w / "i15"]
    err("import object_names.json not a list", rel_names, "object_names")

    def rel_idx():
        rel = _release(w / "rel_idx")
        np.save(rel / "idx_start.npy", np.array([0, -5]))
        return ["data", "import", rel, "--format", "trumans", "--out", w / "i16"]
    err("import idx_start negative", rel_idx, "idx_start")

    # ---- view
    err("view missing sequence", lambda: ["view", w / "nope.npz"], "nope.npz")
    err("view --max-frames 0", lambda: ["view", seq0, "--max-frames", "0", "--out", w / "v1"], "--max-frames")
    err("view --stride 0", lambda: ["view", seq0, "--stride", "0", "--out", w / "v2"], "--stride")
    err("view --stride -1", lambda: ["view", seq0, "--stride", "-1", "--out", w / "v3"], "--stride")
    err("view --scene missing", lambda: ["view", seq0, "--scene", w / "noscene", "--out", w / "v4"], "noscene")

    def view_in(tag, mutate, *must):
        def fn():
            d = D(tag)
            mutate(d)
            return ["view", next((d / "sequences").glob("*.npz")), "--no-animation", "--out", w / f"{tag}_out"]
        err(f"view: {tag}", fn, *must)

    def trunc_occ(d):
        p = next((d / "scenes").iterdir()) / "occupancy.npz"
        p.write_bytes(p.read_bytes()[:1000])
    view_in("truncated occupancy.npz", trunc_occ, "occupancy")
    view_in("scene.json objects is a string", lambda d: _edit_scene(d, lambda s: s.update(objects="abc")),
            "objects")
    view_in("scene.json static entry is a number", lambda d: _edit_scene(d, lambda s: s.update(static=[1])),
            "static")
    view_in("scene.json pose is a string", lambda d: _edit_scene(
        d, lambda s: s["objects"][0].update(pose="eye")), "pose")
    view_in("scene.json meta is a list", lambda d: _edit_scene(d, lambda s: s.update(meta=[1, 2])), "meta")
    view_in("scene.json dynamic is a string", lambda d: _edit_scene(
        d, lambda s: s["objects"][0].update(dynamic="no")), "dynamic")
    view_in("scene.json mesh is a number", lambda d: _edit_scene(
        d, lambda s: s["objects"][0].update(mesh=5)), "mesh")
    view_in("index.json scenes value is a number", lambda d: _edit_index(
        d, lambda i: i["scenes"].update({k: 5 for k in i["scenes"]})), "scenes")
    view_in("index.json is not JSON", lambda d: (d / "index.json").write_text("{oops"), "index.json")

    def zero_seq():
        return ["view", _zero_length(w / "zero.npz"), "--out", w / "v5"]
    err("view zero-length sequence", zero_seq, "frame")

    def str_joints():
        p = w / "strj.npz"
        np.savez(p, joints=np.array([["a"] * 3] * 24).reshape(1, 24, 3), fps=np.float32(30))
        return ["view", p, "--out", w / "v6"]
    err("view joints are strings", str_joints, "joints")

    def fps_vec():
        p = w / "fpsv.npz"
        np.savez(p, joints=np.zeros((3, 24, 3), np.float32), fps=np.array([30.0, 30.0]))
        return ["view", p, "--out", w / "v7"]
    err("view fps is a vector", fps_vec, "fps")

    def trunc_seq():
        p = w / "trunc.npz"
        p.write_bytes(seq0.read_bytes()[:500])
        return ["view", p, "--out", w / "v8"]
    err("view truncated sequence", trunc_seq, "trunc.npz")

    # ---- augment
    def aug(tag_out, *extra, data=None):
        return lambda: ["augment", "--data", data or aug_base, "--out", w / tag_out, "--workers", "1",
                        "--variations", "1", *extra]
    for flag, val, must in (("--window", "nan", "window"), ("--window", "0", "window"), ("--threshold", "nan", "threshold"),
                            ("--threshold", "-0.5", "threshold"), ("--variations", "0", "variations"),
                            ("--workers", "-1", "workers"), ("--max-unreachable", "2", "unreachable"),
                            ("--max-unreachable", "nan", "unreachable"), ("--splits", "dev", "dev")):
        err(f"augment {flag} {val}", lambda f=flag, v=val: aug(f"a_{f}_{v}")() + [f, v], must)
    err("augment --variations 100000", lambda: aug("a_var")() + ["--variations", "100000"], "variations",
        timeout=40)
    err("augment --data missing", lambda: ["augment", "--data", w / "nodata", "--out", w / "a1"], "nodata")

    def aug_self():
        d = D("a_self")
        before = _snapshot(d)
        rc, _, e = call(["augment", "--data", d, "--out", d, "--workers", "1", "--variations", "1"], 120)
        changed = _snapshot(d) != before
        if rc == 0 or changed:
            return "silent", [f"rc={rc} changed={changed}"]
        return classify_error(rc, e, ("--out",)), e.strip().splitlines()[-1:]
    custom("augment --out = --data", aug_self)

    def aug_foreign():
        d = D("a_foreign")
        before = _snapshot(d)
        rc, _, e = call(["augment", "--data", aug_base, "--out", d, "--workers", "1", "--variations", "1"], 120)
        changed = _snapshot(d) != before
        if rc == 0 or changed:
            return "silent", [f"rc={rc} changed={changed}"]
        return classify_error(rc, e, ("--overwrite",)), e.strip().splitlines()[-1:]
    custom("augment --out holds another dataset", aug_foreign)

    def bad_data(tag, mutate, *must):
        def fn():
            d = D(tag)
            mutate(d)
            return ["augment", "--data", d, "--out", w / f"{tag}_out", "--workers", "1", "--variations", "1"]
        err(f"augment data: {tag}", fn, *must)
    bad_data("index splits hold numbers", lambda d: _edit_index(d, lambda i: i["splits"].update(train=[1, 2])),
             "splits")
    bad_data("index splits hold a string", lambda d: _edit_index(d, lambda i: i["splits"].update(train="x.npz")),
             "splits")
    bad_data("index fps is text", lambda d: _edit_index(d, lambda i: i.update(fps="abc")), "fps")
    bad_data("index fps is 0", lambda d: _edit_index(d, lambda i: i.update(fps=0)), "fps")
    bad_data("index vocabulary holds numbers", lambda d: _edit_index(d, lambda i: i.update(vocabulary=[1, 2])),
             "vocabulary")
    bad_data("index scenes value is a number", lambda d: _edit_index(
        d, lambda i: i["scenes"].update({k: 5 for k in i["scenes"]})), "scenes")
    bad_data("index is a list", lambda d: (d / "index.json").write_text("[1, 2]"), "index.json")
    bad_data("index path escapes the folder", lambda d: _edit_index(
        d, lambda i: i["splits"].update(train=["../../etc/hostname"])), "..")

    def zero_in_ds(d):
        p = next((d / "sequences").glob("*.npz"))
        z = dict(np.load(p, allow_pickle=False))
        for k, v in z.items():
            if v.ndim and v.shape[0] == z["joints"].shape[0] and k != "action_names":
                z[k] = v[:0]
        np.savez(p, **z)
    bad_data("zero-length sequence", zero_in_ds, "frame")
    bad_data("truncated sequence", lambda d: (lambda p: p.write_bytes(p.read_bytes()[:300]))(
        next((d / "sequences").glob("*.npz"))), ".npz")
    bad_data("scene.json objects is a string", lambda d: _edit_scene(d, lambda s: s.update(objects="abc")),
             "objects")
    bad_data("scene.json pose wrong shape", lambda d: _edit_scene(
        d, lambda s: s["objects"][0].update(pose=[1, 2, 3])), "pose")
    bad_data("scene mesh file truncated", lambda d: (lambda p: p.write_bytes(p.read_bytes()[:100]))(
        next(next((d / "scenes").iterdir()).glob("objects/*.ply"))), ".ply")

    def stale_scene():
        d = D("a_stale")
        out = w / "a_stale_out"
        rc1, _, e1 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        if rc1 != 0:
            return "traceback" if "Traceback" in e1 else "other", e1.strip().splitlines()[-1:]
        first = {p.name: p.read_bytes() for p in (out / "sequences").glob("*.npz")}
        # move every object of the source scene by 5 cm: the outputs depend on it
        _edit_scene(d, lambda s: [o["pose"][0].__setitem__(3, o["pose"][0][3] + 0.05) for o in s["objects"]])
        rc2, _, e2 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        second = {p.name: p.read_bytes() for p in (out / "sequences").glob("*.npz")}
        if rc2 == 0 and first == second:
            return "silent", ["rerun after a scene change returned the old outputs"]
        return ("ok" if rc2 == 0 else classify_error(rc2, e2, ())), [f"rc={rc2} outputs changed"]
    custom("augment resume after the scene changed", stale_scene)

    def failed_then_fixed():
        d = D("a_fail")
        out = w / "a_fail_out"
        keep = json.loads((next((d / "scenes").iterdir()) / "scene.json").read_text())
        # move every object 50 m away: no contact with any interactable object -> the source fails
        _edit_scene(d, lambda s: [o["pose"][0].__setitem__(3, o["pose"][0][3] + 50) for o in s["objects"]])
        rc1, _, e1 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        (next((d / "scenes").iterdir()) / "scene.json").write_text(json.dumps(keep))
        rc2, _, e2 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        n2 = len(list((out / "sequences").glob("*.npz"))) if (out / "sequences").is_dir() else 0
        notes = [f"first run rc={rc1}; after the fix rc={rc2}, outputs={n2}"]
        if n2 == 0:
            return "silent", notes
        return "ok", notes
    custom("augment source without contact, redone after the scene is fixed", failed_then_fixed)

    def broken_source():
        d = D("a_broken")
        out = w / "a_broken_out"
        mesh = next(next((d / "scenes").iterdir()).glob("objects/*.ply"))
        keep = mesh.read_bytes()
        mesh.write_bytes(b"ply\nformat garbage\n")
        rc1, o1, e1 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        mesh.write_bytes(keep)
        rc2, _, e2 = call(["augment", "--data", d, "--out", out, "--workers", "1", "--variations", "1"], 300)
        n2 = len(list((out / "sequences").glob("*.npz"))) if (out / "sequences").is_dir() else 0
        notes = [f"broken run rc={rc1}; after the fix rc={rc2}, outputs={n2}"]
        if rc1 == 0 or n2 == 0 or rc2 != 0:
            return "silent", notes
        return classify_error(rc1, e1, ("failed",)), e1.strip().splitlines()[-1:]
    custom("augment source that fails: exit status, retried after fix", broken_source)

    def workers_cap():
        rc, out, e = call(["augment", "--data", aug_base, "--out", w / "a_cap", "--workers", "12",
                           "--variations", "1", "--json"], 300)
        if rc != 0:
            return classify_error(rc, e, ()), e.strip().splitlines()[-1:]
        n = json.loads(out.strip().splitlines()[-1])["workers"]
        return ("silent" if n > 1 else "ok"), [f"workers used: {n} for 1 source"]
    custom("augment --workers 12 for one sequence", workers_cap)

    def two_writers():
        out = w / "a_two"
        env = dict(os.environ, OMP_NUM_THREADS="1")
        cmd = [sys.executable, "-m", "trumans", "augment", "--data", str(aug_base), "--out", str(out),
               "--workers", "1", "--variations", "2"]
        p1 = subprocess.Popen(cmd + ["--seed", "0"], cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True)
        t0 = time.time()
        while not out.exists() and time.time() - t0 < 60:
            time.sleep(0.05)
        p2 = subprocess.run(cmd + ["--seed", "1"], cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True)
        p1.wait()
        if p2.returncode == 0:
            return "silent", ["second writer exit 0 (mixed dataset)"]
        last = p2.stderr.strip().splitlines()[-1:]
        # refused by the lock (first still running) or by the claim (first done): both name the conflict
        out_ = classify_error(p2.returncode, p2.stderr, ())
        if out_ == "clean" and not any(k in last[0] for k in ("being written", "other settings")):
            out_ = "unclear"
        return out_, last
    custom("augment: two writers into one folder", two_writers)

    # ---- eval augment
    err("eval augment over zero sequences", lambda: ["eval", "augment", "--data", base, "--split", "val"], "val")
    err("eval augment --max-seqs 0", lambda: ["eval", "augment", "--data", base, "--max-seqs", "0",
                                              "--split", "train"], "--max-seqs")
    err("eval augment --variations 0", lambda: ["eval", "augment", "--data", base, "--variations", "0",
                                                "--split", "train"], "variations")
    err("eval augment --cases 0", lambda: ["eval", "augment", "--cases", "0"], "cases")
    err("eval augment --split dev", lambda: ["eval", "augment", "--data", base, "--split", "dev"], "dev")

    # ---- other commands (the error channel only)
    err("eval local-query --voxel nan", lambda: ["eval", "local-query", "--voxel", "nan", "--runs", "1"], "voxel")
    err("eval local-query --batch 0", lambda: ["eval", "local-query", "--batch", "0"], "batch")
    err("eval train missing checkpoint", lambda: ["eval", "train", w / "nope.pt"], "nope.pt")

    def garbage_pt():
        p = w / "garbage.pt"
        p.write_bytes(b"garbage")
        return ["eval", "train", p]
    err("eval train garbage checkpoint", garbage_pt, "garbage.pt")
    err("train --data missing", lambda: ["train", "--data", w / "nodata", "--out", w / "t1", "--steps", "1"],
        "nodata")
    err("train --config missing", lambda: ["train", "--config", w / "none.toml", "--data", base, "--out", w / "t2"],
        "none.toml")
    err("train --ablate bogus", lambda: ["train", "--ablate", "bogus", "--data", base, "--out", w / "t3"], "bogus")
    err("unknown command", lambda: ["frobnicate"], "frobnicate")
    err("sample without --out", lambda: ["sample"], "--out")
    err("augment --variations abc", lambda: aug("a_abc")() + ["--variations", "abc"], "--variations")

    # ---- size budgets (issue 39 point 3): refused before allocating, naming the limit
    def toml(text):
        def fn():
            p = w / f"cfg{abs(hash(text)) % 10000}.toml"
            p.write_text(text + "\n")
            return ["train", "--config", p, "--data", base, "--out", w / "t_size"]
        return fn
    for text, must in (("[data]\ngrid = 1024", "MAX_GRID"), ("[model]\nd_model = 1048576", "MAX_PARAMETERS"),
                       ("[model]\nheads = 0", "heads"), ("[model]\nlayers = 0", "layers"),
                       ("[scene]\nheads = 7", "heads"), ("[train]\nbatch_size = 1000000000", "MAX_BATCH"),
                       ("[train]\nbatch_size = 60000", "MAX_BATCH_BYTES")):
        err(f"train config {text.replace(chr(10), ' ')}", toml(text), must)
    err("synth --rooms 1000000", lambda: ["data", "synth", "--out", w / "s_big", "--rooms", "1000000"], "MAX_ROOMS")
    err("synth --hours 1e9", lambda: ["data", "synth", "--out", w / "s_bigh", "--hours", "1e9"], "MAX_SYNTH_HOURS")
    err("eval augment --cases 100000", lambda: ["eval", "augment", "--cases", "100000"], "MAX_CASES")
    err("eval augment --max-seqs 1e7", lambda: ["eval", "augment", "--data", base, "--max-seqs", "10000000"],
        "MAX_EVAL_SEQUENCES")
    err("sample --num-samples 1000000", lambda: ["sample", "--out", w / "smp" / "x", "--num-samples", "1000000"],
        "MAX_SAMPLES")

    # ---- eval synthesis: every argument checked before sampling (each case would sample for minutes)
    for extra, must in ((["--ablation", "noname"], "NAME=CHECKPOINT"),
                        (["--ablation", f"a={w / 'none.pt'}"], "none.pt"),
                        (["--motion-encoder", w / "enc.pt", "--data", base], "enc.pt"),
                        (["--data", w / "nodata"], "nodata"), (["--data", base], "test split"),
                        (["--save-windows", w / "no" / "w.npz"], "--save-windows"),
                        (["--steps", "100000"], "--steps"), (["--naive-episodes", "100000"], "--naive-episodes")):
        err(f"eval synthesis {' '.join(str(x) for x in extra)[-40:]}", lambda x=extra: ["eval", "synthesis", *x], must,
            timeout=90)

    # ---- inputs that are not regular files: a FIFO never ends a read, a folder or device is not a file
    def special(kind):
        p = w / f"special_{kind}"
        if not p.exists() and not p.is_fifo():
            if kind == "fifo":
                os.mkfifo(p)
            else:
                p.mkdir()
        return p
    for kind in ("fifo", "dir"):
        err(f"import bvh is a {kind}", lambda k=kind: ["data", "import", special(k), "--format", "bvh", "--out",
                                                       w / f"sp_i_{k}"], "special_" + kind, "not a file", timeout=20)
        err(f"import fbx is a {kind}", lambda k=kind: ["data", "import", special(k), "--format", "fbx", "--out",
                                                       w / f"sp_f_{k}"], "not a file", timeout=20)
        err(f"view sequence is a {kind}", lambda k=kind: ["view", special(k), "--out", w / f"sp_v_{k}"],
            "not a file", timeout=20)
        err(f"train --config is a {kind}", lambda k=kind: ["train", "--config", special(k), "--data", base, "--out",
                                                           w / f"sp_t_{k}"], "not a", timeout=20)
        err(f"eval train checkpoint is a {kind}", lambda k=kind: ["eval", "train", special(k)], "not a file",
            timeout=20)
        err(f"augment --data is a {kind}" if kind == "fifo" else "augment --data is a folder without index",
            lambda k=kind: ["augment", "--data", special(k), "--out", w / f"sp_a_{k}"], "special_" + kind, timeout=20)
    err("import bvh is /dev/zero", lambda: ["data", "import", "/dev/zero", "--format", "bvh", "--out", w / "sp_z"],
        "device", timeout=20)
    err("import --action-names is a fifo", lambda: ["data", "import", _release(w / "rel_an"), "--format", "trumans",
                                                    "--out", w / "sp_an", "--action-names", special("fifo")],
        "not a file", timeout=20)

    # ---- JSON / TOML nested past the stated limit (trumans.limits.MAX_NESTING), far past Python's recursion limit
    deep_json = "[" * 100_000 + "]" * 100_000
    def deep_toml():
        p = w / "deep.toml"
        p.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
        return ["train", "--config", p, "--data", base, "--out", w / "t_deep"]
    err("train --config nested 5000 deep", deep_toml, "deep.toml", "MAX_NESTING")
    def deep_index():
        d = D("deep_index")
        (d / "index.json").write_text(deep_json)
        return ["augment", "--data", d, "--out", w / "a_deep"]
    err("augment index.json nested 100000 deep", deep_index, "index.json", "MAX_NESTING")
    def deep_scene():
        d = D("deep_scene")
        (next((d / "scenes").iterdir()) / "scene.json").write_text(deep_json)
        return ["view", next((d / "sequences").glob("*.npz")), "--no-animation", "--out", w / "v_deep"]
    err("view scene.json nested 100000 deep", deep_scene, "scene.json", "MAX_NESTING")
    def deep_map():
        p = w / "deep_map.json"
        p.write_text(deep_json)
        return ["data", "import", BVH, "--format", "bvh", "--out", w / "i_deep", "--joint-map", p]
    err("import --joint-map nested 100000 deep", deep_map, "joint-map", "MAX_NESTING")
    def deep_plan():
        p = w / "deep_plan.json"
        p.write_text(deep_json)
        return ["sample", "--plan", p, "--out", w / "smp_deep" / "x"]
    err("sample --plan nested 100000 deep", deep_plan, "deep_plan.json", "MAX_NESTING")

    # ---- augment: a source listed twice is refused (each is augmented once)
    err("augment index lists a sequence twice", lambda: ["augment", "--data", _edit_index(
        D("a_dup"), lambda i: i["splits"].update(train=i["splits"]["train"] * 2)), "--out", w / "a_dup_out",
        "--workers", "1"], "listed twice")
    err("augment --splits train train", lambda: aug("a_dup2")() + ["--splits", "train", "train"], "split twice")

    def degenerate_seat(kind):
        def thunk():
            import trimesh

            d = D(f"a_seat_{kind}")
            sd = next((d / "scenes").iterdir())
            seats = [o for o in json.loads((sd / "scene.json").read_text())["objects"]
                     if o.get("category") in ("sofa", "chair", "stool")]
            for o in seats:
                (x0, y0, z0), (x1, y1, _) = trimesh.load(sd / o["mesh"], process=False).bounds
                if kind == "open box":  # no bottom, one side missing: not watertight
                    box = trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, 0.45]])
                    keep = (box.face_normals[:, 2] > -0.9) & (box.face_normals[:, 0] < 0.9)
                    m = trimesh.Trimesh(box.vertices, box.faces[keep], process=False)
                elif kind == "flat quad":
                    m = trimesh.Trimesh([[x0, y0, 0.45], [x1, y0, 0.45], [x1, y1, 0.45], [x0, y1, 0.45]],
                                        [[0, 1, 2], [0, 2, 3]], process=False)
                else:
                    m = trimesh.Trimesh([[x0, y0, 0.45], [x1, y0, 0.45], [x0, y1, 0.45]], [[0, 1, 2]], process=False)
                m.export(sd / o["mesh"])
            rc, out, e = call(["augment", "--data", d, "--out", w / f"a_seat_{kind}_out", "--workers", "1",
                               "--variations", "2", "--json"], 300)
            if rc != 0:
                return classify_error(rc, e, ()), e.strip().splitlines()[-1:]
            s = json.loads(out.strip().splitlines()[-1])
            warned = "trumans: warning:" in e
            return ("silent" if s["skipped"] and not warned else "ok"), [f"outputs {s['outputs']}, skipped {s['skipped']}"]
        return thunk
    for kind in ("one triangle", "flat quad", "open box"):
        custom(f"augment {kind} seat meshes keep their contacts", degenerate_seat(kind))

    # ---- outputs: --out empty / the current folder / a dataset's own file; --overwrite keeps the user's files
    err("sample --out empty", lambda: ["sample", "--out", "", "--goto", "1,1"], "--out is empty")
    err("train --out .", lambda: ["train", "--data", base, "--out", "."], "current folder")
    err("sample --out a dataset sequence's stem", lambda: ["sample", "--out", seq0.with_suffix(""), "--goto", "1,1"],
        "a file of the trumans dataset")
    err("refine --out a dataset sequence", lambda: ["refine", seq0, "--out", seq0], "a file of the trumans dataset")

    def overwrite_keeps_user_files():
        out = w / "ow_aug"
        argv = ["augment", "--data", base, "--out", out, "--workers", "1", "--variations", "1"]
        rc, _, e = call(argv, 300)
        if rc != 0:
            return classify_error(rc, e, ()), e.strip().splitlines()[-1:]
        (out / "sequences" / "my_notes.txt").write_text("keep")
        (w / "ow_theirs").mkdir()
        (w / "ow_theirs" / "scene.json").write_text("theirs")
        os.symlink(w / "ow_theirs", out / "scenes" / "their_room")
        rc, _, e = call(argv + ["--seed", "1", "--overwrite"], 300)
        if rc != 0:
            return classify_error(rc, e, ()), e.strip().splitlines()[-1:]
        kept = ((out / "sequences" / "my_notes.txt").is_file() and (out / "scenes" / "their_room").is_symlink()
                and (w / "ow_theirs" / "scene.json").read_text() == "theirs")
        return ("ok" if kept else "silent"), ["user files kept" if kept else "--overwrite deleted a user file"]
    custom("augment --overwrite keeps the user's files in sequences/ and scenes/", overwrite_keeps_user_files)

    # ---- track --anchors: a wrong file is one clear line
    def anchors(tag, write):
        def fn():
            p = w / tag
            write(p)
            return ["track", seq0, "--scene", next((base / "scenes").iterdir()), "--out", w / f"{tag}_out.npz",
                    "--anchors", p]
        return fn
    err("track --anchors is a .npy", anchors("anc.npy", lambda p: np.save(p, np.zeros(3))), "not an .npz")
    err("track --anchors is text", anchors("anc.txt", lambda p: p.write_text("1 2 3")), "not a readable .npz")
    err("track --anchors NaN xy", anchors("anc_nan.npz", lambda p: np.savez(p, frames=np.array([0, 3]),
                                                                           xy=np.full((2, 2), np.nan))), "not finite")
    return cases


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", default="/tmp/trumans_survey")
    p.add_argument("--only", default="", help="run the cases whose name starts with this")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    w = Path(a.work)
    if w.exists():
        shutil.rmtree(w)
    w.mkdir(parents=True)
    base = w / "_base"
    _synth(base)
    aug_base = base
    counts: dict[str, int] = {}
    rows = []
    for name, thunk in build_cases(w, base, aug_base):
        if not name.startswith(a.only):
            continue
        try:
            outcome, note = thunk()
        except Exception as e:  # a fixture step failed: count it as what it is
            outcome, note = "traceback", [f"{type(e).__name__}: {e}"]
        counts[outcome] = counts.get(outcome, 0) + 1
        rows.append({"case": name, "outcome": outcome, "note": (note or [""])[-1][:220]})
        print(f"{outcome:>9}  {name:<48} {rows[-1]['note']}", flush=True)
    print(json.dumps({"cases": len(rows), "counts": counts}))
    if a.json:
        print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
