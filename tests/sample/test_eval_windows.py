"""Generated windows saved by `trumans eval synthesis --save-windows` and their pooled fid."""
import json
import subprocess
import sys

import numpy as np
import pytest

from trumans.sample.eval_synthesis import fid_figures, load_reference, read_windows, write_windows

from helpers import REPO_ROOT



def test_windows_round_trip_and_bad_files(tmp_path):
    rng = np.random.default_rng(0)
    f, y = rng.normal(size=(7, 5)), rng.integers(-1, 4, 7)
    write_windows(tmp_path / "w.npz", f, y)
    g, z = read_windows(tmp_path / "w.npz")
    np.testing.assert_allclose(g, f.astype(np.float32))
    assert z.dtype == np.int64 and np.array_equal(z, y)
    assert [p.name for p in tmp_path.iterdir()] == ["w.npz"]  # no temporary file left behind
    with pytest.raises(ValueError, match="labels"):
        write_windows(tmp_path / "x.npz", f, y[:3])
    assert not (tmp_path / "x.npz").exists()
    with pytest.raises(FileNotFoundError, match="--save-windows"):
        read_windows(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", joints=f)
    with pytest.raises(ValueError, match="not the features"):
        read_windows(tmp_path / "other.npz")
    np.savez(tmp_path / "nan.npz", features=np.full((2, 5), np.nan), labels=np.zeros(2, np.int64))
    with pytest.raises(ValueError, match="finite"):
        read_windows(tmp_path / "nan.npz")


def test_fid_figures_of_real_windows_are_near_the_real_values():
    ref = load_reference()
    if ref is None:
        pytest.skip("no shipped synthesis reference")
    test_f, test_y = ref["features"], ref["labels"]
    same = fid_figures(test_f, test_y, ref)  # the reference against itself
    assert same["fid"] < 1e-3 and same["fid_matched"] < 1e-3
    assert same["windows"] == len(test_f)
    # train windows: a real set, so about the real-vs-real value, and more windows -> less bias
    small = fid_figures(ref["train_features"][:150], ref["train_labels"][:150], ref)
    big = fid_figures(ref["train_features"][:600], ref["train_labels"][:600], ref)
    assert big["fid"] < small["fid"]
    assert big["real_fid_same_size"] < small["real_fid_same_size"]
    assert 0.5 < big["fid"] / big["real_fid_same_size"] < 2.0


def test_pooled_fid_script(tmp_path):
    ref = load_reference()
    if ref is None:
        pytest.skip("no shipped synthesis reference")
    tf, ty = ref["train_features"], ref["train_labels"]
    for i in range(2):
        write_windows(tmp_path / f"a{i}.npz", tf[i * 100:(i + 1) * 100], ty[i * 100:(i + 1) * 100])
    noisy = tf[:200] + np.random.default_rng(0).normal(0, 3 * tf.std(), tf[:200].shape)
    write_windows(tmp_path / "b.npz", noisy, ty[:200])
    run = subprocess.run([sys.executable, str(REPO_ROOT / "benchmarks" / "pooled_fid.py"),
                          f"real={tmp_path / 'a0.npz'},{tmp_path / 'a1.npz'}", f"noisy={tmp_path / 'b.npz'}"],
                         capture_output=True, text=True, cwd=REPO_ROOT, check=True)
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["real"]["pooled"]["windows"] == 200 and len(out["real"]["each"]) == 2
    pooled = fid_figures(tf[:200], ty[:200], ref)
    assert out["real"]["pooled"]["fid"] == pytest.approx(pooled["fid"], rel=1e-4)
    assert out["ratio_real_over_noisy_fid"] < 0.5  # noise moves the Gaussian away from the real one
