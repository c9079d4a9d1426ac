"""One contact model per dof class (iReplica supp. §10.1): labels, training, checkpoints, routing."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from trumans.model.checkpoint import resign_checkpoint
from trumans.track.interactions import contact_probabilities, interval_classes
from trumans.train.tasks.contact import ContactTask, load_contact_data
from trumans.track.model_io import load_contact_models, save_predictor
from trumans.track.per_dof import DOFS, combine_dof_probabilities, dof_hand_labels, predict_dof_contacts
from trumans.track.postprocess import contact_mask, contact_segments
from trumans.track.predictor import CLASSES, ContactPredictor, ContactPredictorConfig, predict_contacts
from trumans.rotations import axis_angle_to_matrix, matrix_to_6d

from helpers import tiny_contact_dataset

TINY = ContactPredictorConfig(window=9, d_model=8, hidden=8, heads=2, layers=1, ff=8, dropout=0.0)


def _model(seed: int) -> ContactPredictor:
    torch.manual_seed(seed)
    return ContactPredictor(TINY).eval()


def test_labels_keep_only_the_models_class():
    # frames: 0-1 none (leaning on a table), 2-3 slide, 4-5 hinge, 6 free
    hands = np.array([[1, 0], [1, 1], [1, 0], [0, 1], [1, 1], [0, 0], [1, 0]], bool)
    classes = np.array([0, 0, 1, 1, 2, 2, 3])
    assert dof_hand_labels(hands, classes, "slide").tolist() == [[0, 0], [0, 0], [1, 0], [0, 1], [0, 0], [0, 0], [0, 0]]
    assert dof_hand_labels(hands, classes, "hinge").tolist() == [[0, 0]] * 4 + [[1, 1], [0, 0], [0, 0]]
    assert dof_hand_labels(hands.astype(np.float32), classes, "free").sum() == 1  # {0, 1} floats as from the task
    # every contact during a movable class belongs to exactly one dof's model; static contacts to none
    per = sum(dof_hand_labels(hands, classes, d).astype(int) for d in DOFS)
    assert (per == (hands & (classes > 0)[:, None])).all()
    with pytest.raises(ValueError, match="unknown dof class 'door'"):
        dof_hand_labels(hands, classes, "door")
    with pytest.raises(ValueError, match="unknown dof class 'all'"):
        dof_hand_labels(hands, classes, "all")
    with pytest.raises(ValueError, match=r"\(T, 2\)"):
        dof_hand_labels(hands[:, :1], classes, "slide")


def test_combined_probabilities_and_interval_class_follow_the_model_that_fires():
    T = 80
    slide, hinge = np.zeros((T, 2), np.float32), np.zeros((T, 2), np.float32)
    slide[5:15, 1] = 0.9  # the slide model fires on the right hand
    hinge[12:14, 1] = 0.6  # the hinge model fires weakly inside it
    hinge[45:60] = 0.8  # and alone, on both hands, 1 s later
    prob, scores = combine_dof_probabilities({"slide": slide, "hinge": hinge})
    assert np.allclose(prob, np.maximum(slide, hinge))
    assert scores.shape == (T, len(CLASSES)) and (scores[:, CLASSES.index("none")] == 0).all()
    assert (scores[:, CLASSES.index("free")] == 0).all()  # no free model given
    assert np.allclose(scores[:, CLASSES.index("slide")], slide.max(1))
    segs = contact_segments(contact_mask(prob, 30.0))
    assert interval_classes(scores, segs) == {0: "slide", 1: "hinge"}
    with pytest.raises(ValueError, match="at least one"):
        combine_dof_probabilities({})
    with pytest.raises(ValueError, match=r"\(T, 2\)"):
        combine_dof_probabilities({"slide": slide, "hinge": hinge[:-1]})
    with pytest.raises(ValueError, match="unknown dof class"):
        combine_dof_probabilities({"door": slide})


def test_per_dof_models_predict_in_parallel():
    rng = np.random.default_rng(0)
    rot = matrix_to_6d(axis_angle_to_matrix(rng.normal(0, 0.4, (20, 24, 3)))).astype(np.float32)
    models = {"slide": _model(0), "hinge": _model(1), "free": _model(2)}
    prob, scores = predict_dof_contacts(models, rot)
    each = {d: predict_contacts(m, rot)[0] for d, m in models.items()}
    assert np.allclose(prob, np.max(np.stack(list(each.values())), 0))
    for d in DOFS:
        assert np.allclose(scores[:, CLASSES.index(d)], each[d].max(1))
    # through the tracker's entry point, also at another frame rate (resampled to the models' 30 fps)
    p2, s2 = contact_probabilities(models, rot, 30.0)
    assert np.allclose(p2, prob) and np.allclose(s2, scores)
    p60, _ = contact_probabilities(models, np.repeat(rot, 2, axis=0), 60.0)
    assert p60.shape == (40, 2)
    with pytest.raises(ValueError, match="no contact model"):
        contact_probabilities({}, rot, 30.0)


def _save(tmp_path, name: str, dof: str, seed: int = 0):
    path = tmp_path / f"{name}.pt"
    save_predictor(_model(seed), path, dof=dof)
    return path


def test_checkpoint_routing_and_bad_inputs(tmp_path):
    paths = {d: _save(tmp_path, d, d, seed=i) for i, d in enumerate(DOFS)}
    head = _save(tmp_path, "head", "all")
    models = load_contact_models([f"{d}={p}" for d, p in paths.items()])
    assert list(models) == list(DOFS)
    rot = matrix_to_6d(axis_angle_to_matrix(np.random.default_rng(1).normal(0, 0.4, (12, 24, 3)))).astype(np.float32)
    for i, d in enumerate(DOFS):  # each dof gets its own checkpoint's weights
        assert np.allclose(predict_contacts(models[d], rot)[0], predict_contacts(_model(i), rot)[0])
    assert isinstance(load_contact_models([str(head)]), ContactPredictor)
    assert set(load_contact_models([f"hinge={paths['hinge']}"])) == {"hinge"}  # a subset of the dofs is allowed
    with pytest.raises(ValueError, match=r"per-dof model \(dof 'slide'\); pass it as slide="):
        load_contact_models([str(paths["slide"])])
    with pytest.raises(ValueError, match="is a model with a class head"):
        load_contact_models([f"slide={head}"])
    with pytest.raises(ValueError, match="is the per-dof model of 'hinge', not a 'slide' model"):
        load_contact_models([f"slide={paths['hinge']}", f"free={paths['free']}"])
    with pytest.raises(ValueError, match="unknown dof class 'door'"):
        load_contact_models([f"door={paths['hinge']}"])
    with pytest.raises(ValueError, match="given twice"):
        load_contact_models([f"slide={paths['slide']}", f"slide={paths['slide']}"])
    with pytest.raises(ValueError, match="DOF=PATH"):
        load_contact_models([f"slide={paths['slide']}", str(paths["hinge"])])
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_contact_models([f"slide={tmp_path / 'missing.pt'}"])
    torch.save({"format": "trumans-checkpoint", "format_version": 1, "kind": "generator"}, tmp_path / "gen.pt")
    resign_checkpoint(tmp_path / "gen.pt")  # a signed file of another kind
    with pytest.raises(ValueError, match="'contact' checkpoint is needed"):
        load_contact_models([f"slide={tmp_path / 'gen.pt'}"])
    with pytest.raises(ValueError, match="unknown dof class 'door'"):
        save_predictor(_model(0), tmp_path / "x.pt", dof="door")


def test_eval_and_refine_command_lines_take_per_dof_checkpoints(tmp_path, capsys):
    import json

    from trumans.track.evaluate import main as eval_main
    from trumans.track.cli import main as interactions_main
    from trumans.dataset import Dataset
    from trumans.sequence import load_sequence

    paths = {d: _save(tmp_path, d, d, seed=i) for i, d in enumerate(DOFS)}
    with pytest.raises(ValueError, match="unknown dof class 'door'"):
        eval_main([f"door={paths['slide']}"])
    with pytest.raises(ValueError, match="pass it as slide="):
        eval_main([str(paths["slide"])])
    ds = Dataset(tiny_contact_dataset(tmp_path / "data"))
    seq_path = ds.root / ds.split("val")[0]
    scene = str(ds.scene_dir(load_sequence(seq_path).scene))
    args = [str(seq_path), "--scene", scene, "--out", str(tmp_path / "o.npz"), "--json"]
    with pytest.raises(ValueError, match="not a 'hinge' model"):
        interactions_main(args + ["--contact-checkpoint", f"hinge={paths['slide']}"])
    capsys.readouterr()
    assert interactions_main(args + [a for d, p in paths.items() for a in ("--contact-checkpoint", f"{d}={p}")]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["frames"] == load_sequence(tmp_path / "o.npz").num_frames
    # the benchmark with the per-dof set: the toy clips only touch a static table, so every contact
    # is a non-interaction one (no interaction positives: AP undefined, recall 0)
    specs = [f"{d}={p}" for d, p in paths.items()]
    assert eval_main(specs + ["--data", str(ds.root), "--split", "val", "--json"]) == 0
    fig = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert fig["checkpoint"] == " ".join(specs) and fig["sequences"] == 1
    assert fig["ap_interaction"] is None and fig["recall_interaction"] == 0.0 and 0 <= fig["ap"] <= 1


def test_per_dof_task_config_labels_and_checkpoint(tmp_path):
    from trumans.train.loop import train
    from trumans.track.model_io import load_predictor
    from trumans.dataset import Dataset

    task = ContactTask.from_config("slide")
    assert task.config.data.dof == "slide" and task.config.data.class_weight == 0.0
    with pytest.raises(ValueError, match="set class_weight = 0"):
        ContactTask.from_config(None, overrides={"data": {"dof": "hinge"}})
    with pytest.raises(ValueError, match="unknown dof class 'door'"):
        ContactTask.from_config(None, overrides={"data": {"dof": "door"}})
    data = tiny_contact_dataset(tmp_path / "data")
    ds = Dataset(data)
    # the toy clips touch a static table: contacts for the class-head model, negatives for a dof model
    assert load_contact_data(ds, "train", 30.0).hands.sum() > 0
    assert load_contact_data(ds, "train", 30.0, dof="slide").hands.sum() == 0
    tiny = {"model": {"d_model": 8, "hidden": 8, "heads": 2, "layers": 1, "ff": 8, "window": 15},
            "train": {"batch_size": 4, "val_every": 2, "checkpoint_every": 2}, "data": {"val_stride": 10}}
    res = train(ContactTask.from_config("free", overrides=tiny), data, tmp_path / "run", steps=2, progress=False)
    assert res.steps == 2
    _, info = load_predictor(tmp_path / "run" / "checkpoint.pt")
    assert info["dof"] == "free" and info["extra"]["dof"] == "free"
    assert "ap" in info["meta"]["val_figures"] and "class_accuracy" not in info["meta"]["val_figures"]
    assert set(load_contact_models([f"free={tmp_path / 'run' / 'checkpoint.pt'}"])) == {"free"}
