"""The one-call Python API (``trumans.generate``, ``refine_tracked``, ``track_interactions``) and the
scene a sampled sequence records, which ``trumans view`` draws again."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import trumans
from trumans.cli import console_main
from trumans.model.checkpoint import save_checkpoint
from trumans.sample.generate import generate_sequences
from trumans.sequence import load_sequence

from helpers import SAMPLE_VOCAB, tiny_checkpoint


@pytest.fixture(scope="module")
def ckpt_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("ck") / "gen.pt"
    save_checkpoint(path, tiny_checkpoint())
    return str(path)


def test_import_trumans_does_not_import_the_jobs():
    code = "import sys, trumans; print(any(m.startswith(('trumans.sample', 'trumans.refine', 'trumans.track', 'trumans.api', 'torch', 'trimesh', 'open3d')) for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "False"
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        trumans.nonsense  # noqa: B018


def test_generate_equals_the_command(ckpt_path, tmp_path):
    plan = [{"do": "goto", "to": [2.4, 3.4]}]
    seq = trumans.generate(plan=plan, scene="room:2", start=(2.4, 2.5), seed=3, checkpoint=ckpt_path,
                           config=None, progress=False)
    rc = console_main(["sample", "--checkpoint", ckpt_path, "--scene", "room:2", "--start", "2.4,2.5", "--goto",
                       "2.4,3.4", "--seed", "3", "--out", str(tmp_path / "walk"), "--formats", "npz", "--no-progress",
                       "--threads", "0"])  # the threads this process has: bit-identical floats
    assert rc == 0
    ref = load_sequence(tmp_path / "walk.npz")
    np.testing.assert_array_equal(seq.joints, ref.joints)
    assert seq.scene == ref.scene == "room:2" and list(seq.action_names) == SAMPLE_VOCAB
    goals, joints = ref.extra["goals"], ref.extra["goal_joints"]  # every episode's goal, for the viewer
    assert goals.shape == (len(joints), 4) and len(goals) >= 1 and np.isfinite(goals).all()
    assert set(joints.tolist()) == {"pelvis"} and (goals[:, 3] == 0).all()  # floor points
    assert (np.diff(goals[:, 0]) > 0).all() and goals[-1, 0] < seq.num_frames
    np.testing.assert_allclose(goals[-1, 1:3], [2.4, 3.4], atol=0.35)  # the last subgoal is the plan's goal


def test_generate_refuses_bad_arguments_before_sampling(ckpt_path):
    with pytest.raises(ValueError, match="num_samples"):
        generate_sequences(None, "room:2", checkpoint=ckpt_path, num_samples=0)
    with pytest.raises(TypeError, match="plan must be"):
        trumans.generate(plan=3.5, scene="room:2", checkpoint=ckpt_path)


@pytest.fixture(scope="module")
def sampled_npz(ckpt_path, tmp_path_factory):
    """A short walk sampled by the command (its npz records the scene it was sampled in)."""
    out = tmp_path_factory.mktemp("walk") / "walk"
    assert console_main(["sample", "--checkpoint", ckpt_path, "--scene", "room:2", "--start", "2.4,2.5", "--goto",
                         "2.4,3.0", "--out", str(out), "--formats", "npz", "--no-progress"]) == 0
    return out.with_suffix(".npz")


def test_view_draws_the_scene_a_sample_records(sampled_npz, tmp_path):
    from trumans.viz.scene_view import sequence_scene_view

    seq = load_sequence(sampled_npz)
    view = sequence_scene_view(tmp_path / "x.npz", seq, None, None)
    assert view is not None and len(view.static) > 3  # the room's walls and furniture, not a floating figure
    bounds = np.concatenate([m.bounds for m in view.static])
    assert bounds[:, 2].max() > 2.0  # walls
    # an explicit spec wins; a missing explicit scene is an error naming the forms
    assert sequence_scene_view(tmp_path / "x.npz", seq, "default", None) is not None
    with pytest.raises(FileNotFoundError, match="room:SEED"):
        sequence_scene_view(tmp_path / "x.npz", seq, str(tmp_path / "nowhere"), None)
    with pytest.raises(ValueError, match="integer seed"):
        sequence_scene_view(tmp_path / "x.npz", seq, "room:x", None)


def test_view_command_renders_a_sampled_npz_with_its_scene(sampled_npz, tmp_path, capsys):
    import json
    import shutil

    npz = shutil.copy(sampled_npz, tmp_path / "walk.npz")  # view writes beside its input
    assert console_main(["view", str(npz), "--no-animation", "--json"]) == 0
    written = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    from PIL import Image

    img = np.asarray(Image.open(written["topdown"]).convert("L"), np.float64)
    assert img.std() > 10  # walls and furniture drawn, not a blank canvas with a path


def test_the_readme_python_example_runs(tmp_path, monkeypatch):
    """The README's ``From Python`` block, run as written (shipped model) from an empty folder."""
    from helpers import REPO_ROOT

    text = (REPO_ROOT / "README.md").read_text()
    block = text.split("### From Python", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    exec(compile(block, "README.md", "exec"), {})
    seq = load_sequence(tmp_path / "out" / "api_walk.npz")
    assert seq.scene == "room:2" and seq.joints.shape[1:] == (24, 3)
    final = seq.joints[-1, 0, :2]
    assert np.linalg.norm(final - [2.4, 3.4]) < 0.3  # it walked to its goal
