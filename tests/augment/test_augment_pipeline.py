"""The dataset pipeline: outputs in the dataset format, manifest, resume after interruption, bad inputs."""
import json
import os

import numpy as np
import pytest

from trumans.augment.pipeline import PipelineConfig, augment_dataset
from trumans.synth.cases import make_case
from trumans.scenes.io import save_scene
from trumans.scenes.scene import Scene, SceneObject
from trumans.dataset import Dataset, write_index
from trumans.sequence import save_sequence


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("src")
    seqs, scenes = [], {}
    for kind, seed in (("sit", 11), ("hand", 12)):
        seq, scene = make_case(kind, seed)
        save_scene(scene, root / "scenes" / scene.name)
        scenes[scene.name] = f"scenes/{scene.name}"
        save_sequence(seq, root / "sequences" / f"{kind}.npz")
        seqs.append(f"sequences/{kind}.npz")
    # a clip whose scene has nothing near the person: no contact to preserve
    seq, scene = make_case("hand", 13)
    t = scene.objects["table"]
    far = SceneObject("table", "table", t.mesh, pose=np.array([[1, 0, 0, 6.0], [0, 1, 0, 6.0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    lonely = Scene("toy_lonely", objects={"table": far})
    seq.scene = lonely.name
    save_scene(lonely, root / "scenes" / lonely.name)
    scenes[lonely.name] = f"scenes/{lonely.name}"
    save_sequence(seq, root / "sequences" / "lonely.npz")
    seqs.append("sequences/lonely.npz")
    write_index(root, {"name": "toy", "version": "1", "fps": 30.0, "vocabulary": [], "splits": {"train": seqs},
                       "scenes": scenes})
    return root


def test_pipeline_writes_a_dataset_with_manifest_and_resumes(data, tmp_path):
    out = tmp_path / "aug"
    cfg = PipelineConfig(data=str(data), out=str(out), variations=2, kinds=("scale", "move"), workers=1, seed=3)
    s = augment_dataset(cfg, progress=False)
    assert s["outputs"] == 4 and s["sources"] == 3
    assert s["errors"] == [] and s["nothing_to_augment"] == 1  # the lonely clip touches nothing
    assert s["contact_frames"] > 0 and 0.0 <= s["unreachable_frac"] <= 1.0 and s["frames_per_s"] > 0
    assert s["unreachable_frac"] == pytest.approx(s["unreachable_frames"] / s["contact_frames"])
    assert s["contact_err_cm"] < 1.0
    ds = Dataset(out)
    assert len(ds) == 4
    man = json.loads((out / "manifest.json").read_text())
    for o in man["outputs"]:
        assert o["variations"][0]["kind"] in ("scale", "move")
        assert o["contact_err_cm"] < 1.0 and o["changed_intervals"]
        seq = ds.load(o["sequence"])
        assert seq.scene == o["scene"]
        sc = ds.scene(seq.scene)
        assert o["object"] in sc.objects
    # resume: nothing to redo -> the outputs are not rewritten
    files = sorted((out / "sequences").glob("*.npz"))
    mt = {f: f.stat().st_mtime_ns for f in files}
    s2 = augment_dataset(cfg, progress=False)
    assert s2["outputs"] == 4
    assert all(f.stat().st_mtime_ns == mt[f] for f in files)
    # interruption: one source's record and outputs are gone -> only that source is redone
    before = np.load(out / "sequences" / "sit__chair_v0.npz", allow_pickle=False)["joints"]
    (out / "records" / "sit.json").unlink()
    for f in (out / "sequences").glob("sit__*.npz"):
        f.unlink()
    s3 = augment_dataset(cfg, progress=False)
    assert s3["outputs"] == 4 and (out / "records" / "sit.json").is_file()
    assert all(f.stat().st_mtime_ns == mt[f] for f in files if not f.name.startswith("sit__"))
    # same seed, same outputs
    assert np.array_equal(np.load(out / "sequences" / "sit__chair_v0.npz", allow_pickle=False)["joints"], before)


def test_pipeline_bad_inputs(data, tmp_path):
    with pytest.raises(ValueError, match="variations"):
        PipelineConfig(data=str(data), out=str(tmp_path), variations=0)
    with pytest.raises(ValueError, match="max_unreachable"):
        PipelineConfig(data=str(data), out=str(tmp_path), max_unreachable=1.5)
    with pytest.raises(ValueError, match="kinds"):
        PipelineConfig(data=str(data), out=str(tmp_path), kinds=("squash",))
    with pytest.raises(FileNotFoundError):
        augment_dataset(PipelineConfig(data=str(tmp_path / "nope"), out=str(tmp_path / "o"), workers=1), progress=False)
    with pytest.raises(ValueError, match="unknown split"):
        augment_dataset(PipelineConfig(data=str(data), out=str(tmp_path / "o"), splits=("dev",), workers=1), progress=False)


def test_eval_cli_prints_figures_last(capsys):
    from trumans.cli import main

    assert main(["eval", "augment", "--cases", "1", "--variations", "1", "--seed", "1", "--json"]) == 0
    fig = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for k in ("contact_err_cm", "bone_length_err_mm", "smooth_ratio", "foot_skate_added_cm", "joint_centre_inside_max_cm",
              "unreachable_frac", "frames_per_s"):
        assert np.isfinite(fig[k]), k
    assert fig["outputs"] == 5 and fig["bone_length_err_mm"] < 0.1 and fig["smooth_ratio"] <= 1.0 + 1e-9


def test_pipeline_source_picks_the_real_or_the_procedural_takes(data, tmp_path):
    src = tmp_path / "src"
    src.mkdir()
    for d in ("scenes", "sequences"):
        (src / d).symlink_to(data / d)
    index = json.loads((data / "index.json").read_text())
    index["real"] = {"sequences/sit.npz": "cmu:00_00"}  # as `trumans data synth` lists its mocap takes
    (src / "index.json").write_text(json.dumps(index))
    base = dict(data=str(src), variations=1, kinds=("scale",), workers=1, seed=3)
    real = augment_dataset(PipelineConfig(out=str(tmp_path / "real"), source="real", **base), progress=False)
    assert real["sources"] == 1 and all(p.name.startswith("sit__") for p in (tmp_path / "real" / "sequences").glob("*.npz"))
    proc = augment_dataset(PipelineConfig(out=str(tmp_path / "proc"), source="procedural", **base), progress=False)
    assert proc["sources"] == 2 and not list((tmp_path / "proc" / "sequences").glob("sit__*.npz"))
    # "all" keeps the settings (and so the resume keys) of runs made before the option existed
    assert "source" not in PipelineConfig(out="o", **base).settings()
    assert PipelineConfig(out="o", source="real", **base).settings()["source"] == "real"
    with pytest.raises(ValueError, match="source"):
        PipelineConfig(out="o", source="mocap", **base)
    with pytest.raises(ValueError, match="no real sequences"):
        augment_dataset(PipelineConfig(data=str(data), out=str(tmp_path / "none"), source="real", workers=1), progress=False)
