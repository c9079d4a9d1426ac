"""JSON and TOML inputs nested past trumans.limits.MAX_NESTING (issue 39 points 2 and 6): one
`trumans: error:` line of our own naming the file (or flag), its depth, the limit and the fix, never
Python's recursion wording, and no --out left behind. A file just inside the limit still parses."""
import json
import shutil

import pytest

from trumans.cli import console_main
from trumans.input_files import nesting_depth, parse_json, parse_toml
from trumans.limits import MAX_NESTING

from helpers import CMU_WALK_BVH

DEEP = "[" * 100_000 + "]" * 100_000


def _refused(capsys, argv, *must) -> str:
    rc = console_main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
    assert rc == 2 and len(lines) == 1 and "this is a bug" not in err and "Traceback" not in err, err
    assert "recursion" not in lines[0].lower(), lines[0]
    for m in must:
        assert m in lines[0], (m, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The smallest synthetic dataset (one room, one take): cheap to copy."""
    from trumans.synth.build import SynthConfig, build_dataset

    root = tmp_path_factory.mktemp("nest") / "ds"
    build_dataset(SynthConfig(out=str(root), hours=0.002, rooms=1, seed=2, workers=1, real_share=0), progress=False)
    return root


def test_every_reader_refuses_deep_nesting_with_its_own_message(tiny, tmp_path, capsys):
    limit = f"limit of {MAX_NESTING} (trumans.limits.MAX_NESTING)"
    plan = tmp_path / "plan.json"
    plan.write_text(DEEP)
    _refused(capsys, ["sample", "--plan", plan, "--out", tmp_path / "s" / "x"], f"plan file {plan}", "100000 levels",
             limit, "flat list of steps")
    plan_toml = tmp_path / "plan.toml"
    plan_toml.write_text("steps = " + "[" * 5000 + "]" * 5000 + "\n")
    _refused(capsys, ["sample", "--plan", plan_toml, "--out", tmp_path / "s" / "x"], "plan.toml", "TOML", limit)
    cfg = tmp_path / "deep.toml"
    cfg.write_text("[model]\nd_model = " + "{a = " * 500 + "1" + "}" * 500 + "\n")
    _refused(capsys, ["train", "--config", cfg, "--data", tiny, "--out", tmp_path / "t"], f"config {cfg}", "500 levels",
             limit, "built-in ones")
    jm = tmp_path / "map.json"
    jm.write_text(DEEP)
    _refused(capsys, ["data", "import", CMU_WALK_BVH, "--format", "bvh", "--out", tmp_path / "i", "--joint-map", jm],
             f"--joint-map file {jm}", limit, "flat object")
    _refused(capsys, ["data", "import", CMU_WALK_BVH, "--format", "bvh", "--out", tmp_path / "i", "--joint-map",
                      "{\"a\": " + DEEP[:400] + "}"], "inline --joint-map", limit)
    d = shutil.copytree(tiny, tmp_path / "d1")
    (d / "index.json").write_text(DEEP)
    _refused(capsys, ["augment", "--data", d, "--out", tmp_path / "a", "--workers", "1"],
             f"dataset index {d / 'index.json'}", limit, "rebuild the dataset")
    d = shutil.copytree(tiny, tmp_path / "d2")
    scene_json = next((d / "scenes").iterdir()) / "scene.json"
    scene_json.write_text(DEEP)
    _refused(capsys, ["view", next((d / "sequences").glob("*.npz")), "--no-animation", "--out", tmp_path / "v"],
             f"scene file {scene_json}", limit, "re-save the scene")
    _refused(capsys, ["sample", "--out", tmp_path / "s" / "x", "--set", "guidance.scale=" + DEEP[:400]],
             "--set guidance.scale", limit)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d1", "d2", "deep.toml", "map.json", "plan.json",
                                                         "plan.toml"]


def test_nesting_is_counted_outside_strings_and_the_limit_itself_parses():
    assert nesting_depth('{"a": [1, "[[[[", {"b": []}]}') == 4
    assert nesting_depth('[a.b]\nx = [[1], [2]]  # [[[[\ny = "[[["\nz = \'[[[\'\nw = """\n[[[\n"""\n', toml=True) == 2
    ok = "[" * MAX_NESTING + "]" * MAX_NESTING
    assert json.dumps(parse_json(ok, "x")).count("[") == MAX_NESTING
    assert parse_toml("a = " + ok, "x")["a"] is not None
    with pytest.raises(ValueError, match=f"{MAX_NESTING + 1} levels deep"):
        parse_json("[" + ok + "]", "x")
