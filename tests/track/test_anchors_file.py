"""`trumans track --anchors FILE` with a wrong file (issue 39 point 6): one `trumans: error:` line naming
the file and the fix - never numpy's advice to unpickle, never "unexpected ... bug" - and nothing written."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.cli import console_main
from trumans.track.anchors import read_anchors


@pytest.fixture(scope="module")
def take(tmp_path_factory):
    from trumans.synth.build import SynthConfig, build_dataset

    root = tmp_path_factory.mktemp("anchors") / "ds"
    build_dataset(SynthConfig(out=str(root), hours=0.002, rooms=1, seed=2, workers=1, real_share=0), progress=False)
    return next((root / "sequences").glob("*.npz")), next((root / "scenes").iterdir())


def _bad_files(d):
    np.save(d / "array.npy", np.zeros(3))
    (d / "notes.txt").write_text("frame 3: 1.0, 2.0")
    np.savez(d / "nan.npz", frames=np.array([0, 5]), xy=np.array([[np.nan, 0.0], [1.0, 1.0]]))
    np.savez(d / "objects.npz", frames=np.array([0, 5], dtype=object), xy=np.zeros((2, 2)))
    np.savez(d / "missing.npz", frames=np.array([0, 5]))
    np.savez(d / "halves.npz", frames=np.array([0.5, 5.0]), xy=np.zeros((2, 2)))
    np.savez(d / "lengths.npz", frames=np.array([0, 5, 6]), xy=np.zeros((2, 2)))
    return {"array.npy": "not an .npz archive", "notes.txt": "not a readable .npz archive",
            "nan.npz": "not finite", "objects.npz": "unpickling is refused", "missing.npz": "lacks ['xy']",
            "halves.npz": "whole frame numbers", "lengths.npz": "(K,) and (K, 2)", "absent.npz": "does not exist"}


def test_bad_anchor_files_are_one_clear_line(take, tmp_path, capsys):
    seq, scene = take
    for name, must in _bad_files(tmp_path).items():
        out = tmp_path / f"out_{name}.npz"
        rc = console_main(["track", str(seq), "--scene", str(scene), "--out", str(out), "--anchors",
                           str(tmp_path / name)])
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
        assert rc == 2 and len(lines) == 1 and "this is a bug" not in err, (name, err)
        assert f"{tmp_path / name}" in lines[0] and must in lines[0], (name, lines[0])
        assert "allow_pickle" not in err and not out.exists()


def test_a_good_anchor_file_reads_back(tmp_path):
    np.savez(tmp_path / "a.npz", frames=np.array([0.0, 7.0]), xy=np.array([[0.5, 1.0], [1.5, 2.0]], np.float32))
    frames, xy = read_anchors(tmp_path / "a.npz")
    assert frames.dtype == np.int64 and frames.tolist() == [0, 7]
    assert xy.dtype == np.float64 and xy.tolist() == [[0.5, 1.0], [1.5, 2.0]]
