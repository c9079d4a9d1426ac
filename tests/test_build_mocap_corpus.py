"""scripts/build_mocap_corpus.py (issue 35 point 3): the selection rules, the motion checks, the
conversion job and its cache. The full rebuild needs the FBX-library snapshots and is not run here."""
import runpy
from pathlib import Path

import numpy as np
import pytest

from trumans.mocap_corpus import load_corpus
from trumans.skeleton import JOINT_INDEX

REPO_ROOT = Path(__file__).resolve().parents[1]
BUILD = runpy.run_path(str(REPO_ROOT / "scripts" / "build_mocap_corpus.py"), run_name="build_mocap_corpus")
DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def rules():
    return BUILD["read_rules"](BUILD["RULES_PATH"])


@pytest.mark.parametrize("clip,description,keep", [
    ("13_01", "sit on high stool, stand up", True),
    ("56_03", "vignettes - fists up, wipe window, yawn, stretch, angrily grab, smash against wall", True),
    ("131_01", "Start Walk Stop", False),               # an evaluation fixture of tests/data
    ("77_10", "walk", False),                           # 77_xx are the 139_xx captures
    ("60_01", "salsa dance", False),
    ("55_01", "monkey (human subject)", False),
    ("132_20", "Walk With Arms Out,  balancing", False),  # held-out weird walks stay out of the reference
    ("132_01", "Walk Slow", True),
    ("80_12", "chopping onions", True),                 # not a hop
    ("16_08", "run/jog", True),                         # the motion check judges the speed
    ("01_02", "playground - climb", False),
    ("22_01", "B sits; A pulls up B (2 subjects - subject A)", True),  # the file holds one body
    ("99_01", "", False),
])
def test_rules_decide_by_the_first_match(rules, clip, description, keep):
    got, reason = BUILD["decide"](rules, clip, description)
    assert got is keep and reason


def test_rules_file_errors(tmp_path):
    read = BUILD["read_rules"]
    cases = {
        "pattern,clips,decision,reason\n,,include,x\n": "first row",
        "clips,pattern,decision,reason\n,,keep,x\n": "include|exclude",
        "clips,pattern,decision,reason\n,(walk,include,x\n,,exclude,y\n": "bad regular expression",
        "clips,pattern,decision,reason\n,walk,include,x\n": "must match everything",
    }
    for i, (text, msg) in enumerate(cases.items()):
        f = tmp_path / f"r{i}.csv"
        f.write_text(text)
        with pytest.raises(ValueError, match=msg):
            read(f)


@pytest.fixture(scope="module")
def stool_clip():
    return next(c for c in load_corpus(split="train") if c.name == "13_01")


def test_motion_checks_pass_a_real_clip_and_catch_each_fault(stool_clip):
    check = BUILD["motion_checks"]
    fig, fail = check(stool_clip)
    assert fail is None and fig["min_bone_m"] > 0.03 and fig["speed_p95_mps"] < 3.0
    c = stool_clip
    short = type(c)(c.name, c.subject, c.description, c.split, c.fps, c.joints[:20], c.states[:20])
    assert "shorter" in check(short)[1]
    j = c.joints.copy()
    j[100, JOINT_INDEX["left_wrist"]] += 1.0  # a 1 m spike: 30 m/s
    assert "joint jump" in check(type(c)(c.name, c.subject, "", c.split, c.fps, j, c.states))[1]
    j = c.joints.copy()
    j[:, :, 2] -= 0.3  # the whole body 30 cm under the floor
    assert "under the floor" in check(type(c)(c.name, c.subject, "", c.split, c.fps, j, c.states))[1]
    j = c.joints.copy()
    j[:, :, 2] += 0.5  # standing on a 50 cm platform
    assert "off the floor" in check(type(c)(c.name, c.subject, "", c.split, c.fps, j, c.states))[1]
    j = c.joints.copy()
    j[:, JOINT_INDEX["spine3"]] = j[:, JOINT_INDEX["spine2"]]  # a zero-length upper-spine bone
    assert "zero-length bone" in check(type(c)(c.name, c.subject, "", c.split, c.fps, j, c.states))[1]


def test_convert_job_checks_the_blob_and_caches(tmp_path):
    src = DATA / "cmu_13_10_daz_first56.bvh"
    blob = BUILD["blob_id"](src.read_bytes())
    job = ("13_10", blob, (str(src), None), "reach", str(tmp_path / "cache"))
    name, fresh, err = BUILD["convert_job"](job)
    assert name == "13_10" and err is None and fresh.joints.shape[1:] == (24, 3)
    assert len(list((tmp_path / "cache").glob("13_10_*.npz"))) == 1
    _, cached, _ = BUILD["convert_job"](job)  # read back from the cache: the same clip
    np.testing.assert_array_equal(cached.joints, fresh.joints)
    np.testing.assert_array_equal(cached.states, fresh.states)
    assert (cached.split, cached.subject, cached.fps) == (fresh.split, fresh.subject, fresh.fps)
    with pytest.raises(SystemExit, match="git blob id"):
        BUILD["convert_job"](("13_10", "0" * 40, (str(src), None), "reach", None))


def test_build_refuses_missing_inputs(tmp_path):
    with pytest.raises(SystemExit, match="--raw .* is not a folder"):
        BUILD["main"](["--raw", str(tmp_path / "none"), "--clips", "x", "--mirrors", str(tmp_path),
                       "--library", "x", "--index", "x"])
