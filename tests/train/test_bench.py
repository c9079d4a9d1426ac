"""trumans.train.bench: optimisation steps of a config on random inputs, timed."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.train.bench import bench_steps, main


def test_bench_steps_runs_the_config_and_reports_its_size():
    r = bench_steps("cpu-small", steps=3, batch_size=2, precision="bf16")
    assert r["device"] == "cpu" and r["precision"] == "bf16" and r["batch_size"] == 2 and r["steps"] == 3
    assert r["finite"] and np.isfinite(r["loss"]) and r["loss"] > 0
    assert 0.5e6 < r["parameters"] < 2e6  # cpu-small: 0.88 M
    assert 0 < r["seconds_per_step"] <= r["median_seconds_per_step"]
    assert r["samples_per_s"] == pytest.approx(2 / r["seconds_per_step"])


def test_bench_refuses_bad_input(capsys):
    with pytest.raises(ValueError, match="precision"):
        bench_steps("cpu-small", precision="fp16")
    with pytest.raises(SystemExit):
        main(["--config", "cpu-small", "--precision", "int8"])
    assert "invalid choice" in capsys.readouterr().err
