"""Bad input through the real command line (issue 13): every case exits with status 2 and prints
exactly one `trumans: error:` line naming the problem and the fix, no traceback, and leaves the
disk as it was. Plus: existing data is never overwritten without --overwrite, augment resumes only
what is still valid and retries failures, one writer per folder, save_scene under concurrency."""
import json
import multiprocessing as mp
import shutil

import numpy as np
import pytest

from trumans.cli import console_main
from trumans.dataset import Dataset
from trumans.io_lock import LOCK_FILE, FolderLock
from trumans.synth.build import SynthConfig, build_dataset

from helpers import CMU_WALK_BVH

REPO_BVH = str(CMU_WALK_BVH)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad") / "synth"
    build_dataset(SynthConfig(out=str(root), hours=0.01, rooms=1, seed=0, workers=1), progress=False)
    return root


def _files(root):
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()} \
        if root.exists() else None


def _refused(capsys, argv, *must, watch=()):
    """Run argv; assert the one-line refusal mentioning ``must`` and that ``watch`` folders are unchanged."""
    before = [_files(w) for w in watch]
    rc = console_main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
    assert rc == 2, (rc, err)
    assert len(lines) == 1 and "Traceback" not in err and "this is a bug" not in err, err
    for m in must:
        assert m.lower() in lines[0].lower(), (m, lines[0])
    assert "allow_pickle" not in err and "weights_only" not in err
    for w, b in zip(watch, before):
        assert _files(w) == b, f"{w} changed"
    return lines[0]


def _copy(data, tmp_path, name="d"):
    return shutil.copytree(data, tmp_path / name)


def _edit(path, fn):
    doc = json.loads(path.read_text())
    fn(doc)
    path.write_text(json.dumps(doc))


def _scene_json(root):
    return next((root / "scenes").iterdir()) / "scene.json"


# ----------------------------------------------------------------- values and arguments

ARG_CASES = [
    (["data", "synth", "--hours", "nan"], ["--hours", "finite"]),
    (["data", "synth", "--hours", "0"], ["--hours"]),
    (["data", "synth", "--rooms", "0"], ["--rooms"]),
    (["data", "synth", "--workers", "-1"], ["--workers"]),
    (["augment", "--data", "{data}", "--window", "nan"], ["--window"]),
    (["augment", "--data", "{data}", "--threshold", "nan"], ["--threshold"]),
    (["augment", "--data", "{data}", "--threshold", "-0.5"], ["--threshold"]),
    (["augment", "--data", "{data}", "--variations", "100000"], ["--variations", "50"]),
    (["augment", "--data", "{data}", "--variations", "abc"], ["--variations", "augment --help"]),
    (["augment", "--data", "{data}", "--max-unreachable", "nan"], ["--max-unreachable"]),
    (["augment", "--data", "{data}", "--splits", "dev"], ["dev"]),
    (["view", "{seq}", "--max-frames", "0"], ["--max-frames"]),
    (["view", "{seq}", "--stride", "-1"], ["--stride"]),
    (["eval", "augment", "--data", "{data}", "--split", "val"], ["val", "no sequences"]),
    (["eval", "augment", "--max-seqs", "0"], ["--max-seqs"]),
    (["data", "import", "{tmp}", "{tmp}", "--format", "trumans"], ["exactly one release folder"]),
    (["data", "import", REPO_BVH, "--format", "bvh", "--joint-map", '{"pelvis": 5}'], ["joint-map"]),
    (["data", "import", REPO_BVH, "--format", "bvh", "--joint-map", "{" + "x" * 400], ["joint-map", "json"]),
    (["data", "import", REPO_BVH, "--format", "bvh", "--fps", "nan"], ["--fps"]),
    (["sample"], ["required: --out"]),
    (["frobnicate"], ["frobnicate"]),
]


@pytest.mark.parametrize("argv,must", ARG_CASES, ids=[" ".join(a[:3]) + " " + a[-1][:12] for a, _ in ARG_CASES])
def test_bad_arguments_are_one_line(argv, must, data, tmp_path, capsys):
    seq = next((data / "sequences").glob("*.npz"))
    subs = {"{data}": str(data), "{seq}": str(seq), "{tmp}": str(tmp_path)}
    argv = [subs.get(a, a) for a in argv]
    out = tmp_path / "out"
    if argv[0] in ("augment", "data") and "--out" not in argv:
        argv += ["--out", str(out)]
    _refused(capsys, argv, *must, watch=[data])
    assert not out.exists()


# ----------------------------------------------------------------- files: one loader per kind

def _truncate(p, n=300):
    p.write_bytes(p.read_bytes()[:n])


FILE_CASES = {
    "occupancy truncated": (lambda d: _truncate(next((d / "scenes").iterdir()) / "occupancy.npz"), ["occupancy"]),
    "scene.json objects text": (lambda d: _edit(_scene_json(d), lambda s: s.update(objects="abc")), ["objects"]),
    "scene.json static number": (lambda d: _edit(_scene_json(d), lambda s: s.update(static=[1])), ["static"]),
    "scene.json meta list": (lambda d: _edit(_scene_json(d), lambda s: s.update(meta=[1])), ["meta"]),
    "scene.json pose text": (lambda d: _edit(_scene_json(d), lambda s: s["objects"][0].update(pose="eye")), ["pose"]),
    "scene.json dynamic text": (lambda d: _edit(_scene_json(d), lambda s: s["objects"][0].update(dynamic="no")),
                                ["dynamic"]),
    "scene.json mesh number": (lambda d: _edit(_scene_json(d), lambda s: s["objects"][0].update(mesh=5)), ["mesh"]),
    "index scenes number": (lambda d: _edit(d / "index.json", lambda i: i["scenes"].update(
        {k: 5 for k in i["scenes"]})), ["scenes"]),
    "index splits numbers": (lambda d: _edit(d / "index.json", lambda i: i["splits"].update(train=[1])), ["splits"]),
    "index fps text": (lambda d: _edit(d / "index.json", lambda i: i.update(fps="abc")), ["fps"]),
    "index vocabulary numbers": (lambda d: _edit(d / "index.json", lambda i: i.update(vocabulary=[1])),
                                 ["vocabulary"]),
    "index path escapes": (lambda d: _edit(d / "index.json", lambda i: i["splits"].update(train=["../x.npz"])),
                           ["leaves the dataset folder"]),
    "index not json": (lambda d: (d / "index.json").write_text("{oops"), ["index.json", "not valid json"]),
}


@pytest.mark.parametrize("case", sorted(FILE_CASES))
def test_bad_files_are_one_line(case, data, tmp_path, capsys):
    d = _copy(data, tmp_path)
    mutate, must = FILE_CASES[case]
    mutate(d)
    seq = next((d / "sequences").glob("*.npz"))
    cmd = ["view", seq, "--no-animation", "--out", tmp_path / "v"]
    if case.startswith("index") and "scenes" not in case:
        cmd = ["augment", "--data", d, "--out", tmp_path / "a", "--workers", "1"]
    _refused(capsys, cmd, *must, watch=[d])
    assert not list(tmp_path.glob("v*")) and not (tmp_path / "a").exists()


def test_bad_sequences_are_refused(tmp_path, capsys):
    z = tmp_path / "zero.npz"
    np.savez(z, joints=np.zeros((0, 24, 3), np.float32), fps=np.float32(30))
    _refused(capsys, ["view", z], "zero.npz", "t >= 1")
    v = tmp_path / "fps.npz"
    np.savez(v, joints=np.zeros((2, 24, 3), np.float32), fps=np.array([30.0, 30.0]))
    _refused(capsys, ["view", v], "fps", "one number")
    s = tmp_path / "text.npz"
    np.savez(s, joints=np.full((1, 24, 3), "a"), fps=np.float32(30))
    _refused(capsys, ["view", s], "joints", "numeric")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fps.npz", "text.npz", "zero.npz"]


def _release(folder, n=40, flag=None, joints=None):
    from trumans.importers.trumans_release import Y_UP_TO_Z_UP
    from trumans.skeleton import REST_JOINTS

    folder.mkdir(parents=True)
    zup = REST_JOINTS[None] + np.linspace(0, 1, n)[:, None, None] * np.array([1.0, 0.5, 0.0])
    np.save(folder / "human_joints.npy", (zup @ Y_UP_TO_Z_UP).astype(np.float32) if joints is None else joints)
    if flag is not None:
        np.save(folder / "scene_flag.npy", np.asarray(flag))
        (folder / "Scene").mkdir()
        for k in range(2):
            np.save(folder / "Scene" / f"s{k}.npy", np.zeros((30, 10, 40), bool))
    return folder


def test_bad_release_folders(tmp_path, capsys):
    out = tmp_path / "out"
    zero = _release(tmp_path / "zero", joints=np.zeros((0, 24, 3), np.float32))
    _refused(capsys, ["data", "import", zero, "--format", "trumans", "--out", out], "0 frames")
    neg = _release(tmp_path / "neg", flag=[-1] * 20 + [0] * 20)
    _refused(capsys, ["data", "import", neg, "--format", "trumans", "--out", out], "scene_flag", ">= 0")
    names = _release(tmp_path / "names")
    np.save(names / "object_flag.npy", np.zeros((40, 1), np.int64))
    np.save(names / "object_mat.npy", np.tile(np.eye(4), (40, 1, 1, 1)))
    (names / "object_names.json").write_text('{"a": 1}')
    _refused(capsys, ["data", "import", names, "--format", "trumans", "--out", out], "object_names.json")
    pickled = _release(tmp_path / "pickled", joints=np.array([{"a": 1}], dtype=object))
    _refused(capsys, ["data", "import", pickled, "--format", "trumans", "--out", out], "unpickling is refused")
    assert not out.exists()


# ----------------------------------------------------------------- never overwrite or mix data

def test_existing_data_is_not_overwritten(data, tmp_path, capsys):
    d = _copy(data, tmp_path)
    _refused(capsys, ["augment", "--data", d, "--out", d, "--workers", "1"], "--out", "source dataset", watch=[d])
    rel = _release(tmp_path / "rel")
    _refused(capsys, ["data", "import", rel, "--format", "trumans", "--out", d], "--overwrite", watch=[d])
    _refused(capsys, ["data", "synth", "--out", d, "--hours", "0.01", "--rooms", "1", "--seed", "3"],
             "other settings", "seed", "--overwrite", watch=[d])
    stranger = tmp_path / "mine"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("keep")
    _refused(capsys, ["data", "import", rel, "--format", "trumans", "--out", stranger], "not empty", watch=[stranger])
    # the same import again is fine, and --overwrite replaces another dataset
    imp = tmp_path / "imp"
    assert console_main(["data", "import", str(rel), "--format", "trumans", "--out", str(imp)]) == 0
    assert console_main(["data", "import", str(rel), "--format", "trumans", "--out", str(imp)]) == 0
    assert console_main(["data", "import", str(rel), "--format", "trumans", "--out", str(d), "--overwrite"]) == 0
    ds = Dataset(d)
    assert ds.name.startswith("trumans-import") and not (d / "rooms").exists()
    assert not (d / LOCK_FILE).exists()


def test_second_writer_is_refused_and_stale_lock_taken_over(data, tmp_path, capsys):
    out = tmp_path / "aug"
    with FolderLock(out, "trumans augment (test holder)"):
        line = _refused(capsys, ["augment", "--data", data, "--out", out, "--workers", "1"], "being written",
                        "pid", "choose another --out", watch=[out])
        assert "test holder" in line
    # a lock file whose owner died (no flock held): taken over
    (out / LOCK_FILE).write_text(json.dumps({"pid": 999999999, "command": "dead"}))
    lock = FolderLock(out, "x").acquire()
    assert lock.stale_owner["pid"] == 999999999
    lock.release()
    assert not (out / LOCK_FILE).exists()


# ----------------------------------------------------------------- augment resume and failures

def test_augment_resume_follows_the_scene_and_retries_failures(data, tmp_path, capsys):
    from trumans.augment.pipeline import PipelineConfig, SourcesFailed, augment_dataset

    d = _copy(data, tmp_path)
    out = tmp_path / "aug"
    cfg = PipelineConfig(data=str(d), out=str(out), variations=1, workers=1, kinds=("move",))
    def listed():
        return {p.name: p.read_bytes() for p in Dataset(out).files}

    s1 = augment_dataset(cfg, progress=False)
    first = listed()
    assert s1["outputs"] > 0 and first
    # move every object of the scene by 5 cm: the old outputs are stale and redone
    _edit(_scene_json(d), lambda s: [o["pose"][0].__setitem__(3, o["pose"][0][3] + 0.05) for o in s["objects"]])
    augment_dataset(cfg, progress=False)
    second = listed()
    assert second and all(second[k] != first.get(k) for k in second)
    # a source that fails: the run fails after writing the summary, nothing is cached for it ...
    mesh = next(_scene_json(d).parent.glob("objects/*.ply"))
    keep = mesh.read_bytes()
    mesh.write_bytes(b"ply\nformat garbage\n")
    with pytest.raises(SourcesFailed, match="1 of 1 source sequences failed") as e:
        augment_dataset(cfg, progress=False)
    assert e.value.summary["errors"] and not list((out / "records").glob("*.json"))
    argv = ["augment", "--data", str(d), "--out", str(out), "--workers", "1", "--variations", "1", "--kinds", "move"]
    assert console_main(argv) == 2
    assert "failed" in capsys.readouterr().err
    # ... and it is retried once fixed
    mesh.write_bytes(keep)
    assert console_main(argv) == 0
    assert listed() == second


def test_augment_workers_capped_at_the_work(data, tmp_path, capsys):
    out = tmp_path / "aug"
    assert console_main(["augment", "--data", str(data), "--out", str(out), "--workers", "12",
                         "--variations", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["sources"] == 1 and summary["workers"] == 1


# ----------------------------------------------------------------- concurrency and temp files

def _save_many(args):
    folder, k = args
    from trumans.scenes.io import load_scene, save_scene

    sc = load_scene(folder + ".src")
    for _ in range(k):
        save_scene(sc, folder)
    return True


def test_concurrent_save_scene_never_fails(data, tmp_path):
    src = next((data / "scenes").iterdir())
    target = tmp_path / "room"
    shutil.copytree(src, str(target) + ".src")
    with mp.get_context("fork").Pool(3) as pool:
        assert all(pool.map(_save_many, [(str(target), 12)] * 3))
    from trumans.scenes.io import load_scene

    assert load_scene(target).objects.keys() == load_scene(src).objects.keys()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["room", "room.src"]  # no temp folders left


def test_stale_temp_files_are_swept(data, tmp_path):
    d = _copy(data, tmp_path)
    (d / "sequences" / ".room_000_t00.npz.abc123.tmp").write_bytes(b"half")
    (d / "scenes" / ".room_000.xyz.tmp").mkdir()
    (d / "scenes" / ".room_000.xyz.tmp" / "scene.json").write_text("{}")
    s = build_dataset(SynthConfig(out=str(d), hours=0.01, rooms=1, seed=0, workers=1), progress=False)
    assert s["resumed_rooms"] == 1
    assert not list(d.rglob(".*.tmp"))


def test_eval_synthesis_checks_every_argument_before_sampling(data, tmp_path, capsys, monkeypatch):
    """Each bad argument is refused before the benchmark samples anything (minutes of work)."""
    import trumans.sample.eval_synthesis as es

    def sampled(*a, **k):
        raise AssertionError("the benchmark started sampling before refusing a bad argument")
    monkeypatch.setattr(es, "evaluate", sampled)
    cases = [(["--ablation", "noname"], ["NAME=CHECKPOINT"]),
             (["--ablation", f"a={tmp_path / 'none.pt'}"], ["--ablation a", "none.pt", "does not exist"]),
             (["--ablation", f"a={tmp_path / 'x.pt'}", "--ablation", f"a={tmp_path / 'y.pt'}"], ["given twice"]),
             ([str(tmp_path / "gen.pt")], ["gen.pt", "does not exist"]),
             (["--motion-encoder", tmp_path / "enc.pt", "--data", data], ["enc.pt", "does not exist"]),
             (["--data", tmp_path / "nodata"], ["nodata"]),
             (["--data", data], ["test split"]),  # the one-room fixture has only a train split
             (["--save-windows", tmp_path / "no" / "w.npz"], ["--save-windows", "existing folder"]),
             (["--steps", "100000"], ["--steps 100000", "diffusion steps"]),
             (["--naive-episodes", "100000"], ["--naive-episodes"])]
    for extra, must in cases:
        _refused(capsys, ["eval", "synthesis", *extra], *must, watch=[data])
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_failed_augment_leaves_no_output_folder(data, tmp_path, capsys):
    """Every source failing (here: a truncated sequence) writes no sequence: the run fails with one
    line and removes the --out folder it made, so a corrected rerun is not blocked by it."""
    d = _copy(data, tmp_path)
    _truncate(next((d / "sequences").glob("*.npz")))
    _refused(capsys, ["augment", "--data", d, "--out", tmp_path / "a", "--workers", "1", "--variations", "1"],
             "failed", ".npz", watch=[d])
    assert not (tmp_path / "a").exists()


def test_augment_source_listed_twice_is_refused(data, tmp_path, capsys):
    """Rule: each source is augmented once; an index listing one twice (or --splits naming a split twice)
    is refused before any work, naming the entry."""
    d = _copy(data, tmp_path)
    _edit(d / "index.json", lambda i: i["splits"].update(train=i["splits"]["train"] * 2))
    rel = json.loads((d / "index.json").read_text())["splits"]["train"][0]
    _refused(capsys, ["augment", "--data", d, "--out", tmp_path / "a", "--workers", "1"], rel, "listed twice",
             watch=[d])
    _refused(capsys, ["augment", "--data", data, "--out", tmp_path / "b", "--splits", "train", "train"],
             "split twice", watch=[data])
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def _seat_mesh(kind, bounds, h=0.45):
    """A degenerate seat inside ``bounds`` (2, 3): an open box (no bottom, one side missing: not
    watertight), one flat quad at seat height, or one triangle at seat height."""
    import trimesh

    (x0, y0, z0), (x1, y1, _) = bounds
    if kind == "open box":
        box = trimesh.creation.box(bounds=[[x0, y0, z0], [x1, y1, h]])
        keep = (box.face_normals[:, 2] > -0.9) & (box.face_normals[:, 0] < 0.9)
        m = trimesh.Trimesh(box.vertices, box.faces[keep], process=False)
        assert not m.is_watertight
        return m
    if kind == "flat quad":
        return trimesh.Trimesh([[x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h]], [[0, 1, 2], [0, 2, 3]],
                               process=False)
    return trimesh.Trimesh([[x0, y0, h], [x1, y0, h], [x0, y1, h]], [[0, 1, 2]], process=False)


@pytest.mark.parametrize("kind", ["open box", "flat quad", "one triangle"])
def test_augment_keeps_the_contacts_of_a_degenerate_seat(kind, data, tmp_path, capsys):
    """A seat mesh without an inside (open and not watertight, one flat quad, one triangle at seat
    height) still has its sitting contacts found and preserved: every variation asked for is written
    (none dropped, no warning), and the seat's outputs change the seat's contact intervals."""
    import trimesh

    d = _copy(data, tmp_path)
    scene_dir = next((d / "scenes").iterdir())
    seat = next(o for o in json.loads((scene_dir / "scene.json").read_text())["objects"] if o["name"] == "sofa_0")
    _seat_mesh(kind, trimesh.load(scene_dir / seat["mesh"], process=False).bounds).export(scene_dir / seat["mesh"])
    out = tmp_path / "a"
    assert console_main(["augment", "--data", str(d), "--out", str(out), "--workers", "1", "--variations", "2",
                         "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    outputs = json.loads((out / "manifest.json").read_text())["outputs"]
    sofa = [o for o in outputs if o["object"] == "sofa_0"]
    touched = {o["object"] for o in outputs}
    assert summary["skipped"] == 0 and "warning" not in captured.err
    assert len(outputs) == 2 * len(touched) and len(sofa) == 2
    for o in sofa:
        assert o["contact_frames"] > 0 and any(iv["object"] == "sofa_0" for iv in o["changed_intervals"])


def test_augment_warns_naming_the_objects_whose_variations_it_skips(data, tmp_path, capsys, monkeypatch):
    """Rule: a run that writes fewer variations than asked (every draw of an object put a joint inside
    it or left its contacts unreachable; injected here for sofa_0) says so on stderr, naming each
    object and source, and lists them in the summary; it never shrinks silently."""
    import trumans.augment.pipeline as pipeline

    real = pipeline.vary_sequence

    def every_sofa_draw_fails(*a, **k):
        return [(name, i, None if name == "sofa_0" else res) for name, i, res in real(*a, **k)]

    monkeypatch.setattr(pipeline, "vary_sequence", every_sofa_draw_fails)
    out = tmp_path / "a"
    assert console_main(["augment", "--data", str(data), "--out", str(out), "--workers", "1", "--variations", "2",
                         "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out.strip().splitlines()[-1])
    assert summary["skipped"] == 2 and {s["object"] for s in summary["skipped_outputs"]} == {"sofa_0"}
    warning = [ln for ln in captured.err.splitlines() if ln.startswith("trumans: warning:")]
    assert len(warning) == 1 and f"{summary['skipped']} variation(s) not written" in warning[0]
    for s in summary["skipped_outputs"]:
        assert s["object"] in warning[0] and s["source"] in warning[0]