"""The `trumans` console script: bad input gives one clear line and exit status 2, never a
traceback, and never advice to load a file unsafely."""
import pickle

import pytest

from trumans.cli import console_main, main


def test_bad_inputs_are_one_line_errors(tmp_path, capsys):
    assert console_main(["augment", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("trumans: error: dataset folder") and "Traceback" not in err
    assert "trumans data synth" in err  # names the fix
    # main() itself lets the error propagate, for callers and tests
    with pytest.raises(FileNotFoundError):
        main(["augment", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "o")])


def test_pickled_files_are_refused_without_unsafe_advice(tmp_path, capsys):
    evil = tmp_path / "evil.pt"
    evil.write_bytes(pickle.dumps(OSError, protocol=2))  # a pickled global: weights_only refuses it
    assert console_main(["eval", "train", str(evil)]) == 2
    err = capsys.readouterr().err.lower()
    assert "not a readable trumans checkpoint" in err and "weights_only" not in err and "false" not in err
    note = tmp_path / "seq.npz"
    note.write_bytes(pickle.dumps([1, 2, 3]))
    assert console_main(["view", str(note)]) == 2
    err = capsys.readouterr().err.lower()
    assert "not a readable sequence" in err and "allow_pickle" not in err and "unsafely" not in err


def test_seeds_outside_what_the_generators_take_are_clear_errors(capsys):
    from trumans.cli import console_main

    for seed in ("18446744073709551616", "-1", "1.5"):
        assert console_main(["data", "synth", "--out", "unused", "--seed", seed]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--seed" in err[0] and ("[0, 4294967295]" in err[0] or "whole number" in err[0])


def test_train_refuses_init_and_resume_together(tmp_path, capsys):
    from trumans.cli import console_main

    assert console_main(["train", "--data", str(tmp_path), "--out", str(tmp_path / "run"), "--init",
                         str(tmp_path / "x.pt"), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "--init" in err and "--resume" in err and "give one of them" in err
    assert not (tmp_path / "run").exists()


def test_a_refused_training_run_leaves_no_run_folder(tmp_path, capsys):
    from trumans.cli import console_main

    out = tmp_path / "run"
    assert console_main(["train", "--data", str(tmp_path / "missing"), "--out", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not out.exists()
    out.mkdir()  # a folder the user made is left in place
    assert console_main(["train", "--data", str(tmp_path / "missing"), "--out", str(out)]) == 2
    assert out.is_dir()
