"""Sizes from a config or a flag are checked against the budgets of trumans.limits before anything
is allocated (issue 39 point 3): a model, a voxel grid, a batch, a room or case count too big is one
`trumans: error:` line naming the value, the limit's name and the fix, and no --out is created."""
import pytest
import torch

from trumans import limits
from trumans.cli import console_main
from trumans.model.nets.blocks import encoder_stack
from trumans.model.nets import DenoiserConfig
from trumans.synth.build import SynthConfig


def _refused(capsys, argv, *must):
    rc = console_main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("trumans: error:")]
    assert rc == 2 and len(lines) == 1 and "this is a bug" not in err and "Traceback" not in err, err
    for m in must:
        assert m.lower() in lines[0].lower(), (m, lines[0])
    return lines[0]


TOML_CASES = [
    ("[data]\ngrid = 1024", ["grid", "1024", "MAX_GRID"]),
    ("[model]\nd_model = 1048576", ["d_model 1048576", "MAX_PARAMETERS", "lower d_model"]),
    ("[model]\nlayers = 100000", ["layers 100000", "MAX_PARAMETERS"]),
    ("[model]\nheads = 0", ["denoiser", "heads", ">= 1"]),
    ("[model]\nheads = 7", ["heads (7) must divide d_model"]),
    ("[scene]\nlayers = 0", ["scene perceiver", "layers", ">= 1"]),
    ("[action]\nd_model = 0", ["action encoder", "d_model"]),
    ("[train]\nbatch_size = 1000000000", ["batch_size", "1,000,000,000", "MAX_BATCH"]),
    ("[train]\nval_batch_size = 1000000000", ["val_batch_size", "MAX_BATCH"]),
    ("[train]\nbatch_size = 60000", ["train.batch_size", "GiB", "MAX_BATCH_BYTES"]),
]


@pytest.mark.parametrize("toml,must", TOML_CASES, ids=[t.replace("\n", " ") for t, _ in TOML_CASES])
def test_train_config_sizes_are_refused_before_building(toml, must, tmp_path, capsys):
    cfg = tmp_path / "big.toml"
    cfg.write_text(toml + "\n")
    out = tmp_path / "run"
    _refused(capsys, ["train", "--config", cfg, "--data", tmp_path / "no_data", "--out", out], *must)
    assert not out.exists()


FLAG_CASES = [
    (["data", "synth", "--rooms", "1000000"], ["--rooms", "1,000,000", "10,000", "MAX_ROOMS"]),
    (["data", "synth", "--hours", "1e9"], ["--hours", "MAX_SYNTH_HOURS"]),
    (["augment", "--data", "{tmp}", "--variations", "100000"], ["--variations", "MAX_VARIATIONS"]),
    (["eval", "augment", "--cases", "100000"], ["--cases", "MAX_CASES"]),
    (["eval", "augment", "--max-seqs", "10000000"], ["--max-seqs", "MAX_EVAL_SEQUENCES"]),
    (["sample", "--num-samples", "1000000"], ["--num-samples", "MAX_SAMPLES"]),
]


@pytest.mark.parametrize("argv,must", FLAG_CASES, ids=[" ".join(a[:2] + a[-2:-1]) for a, _ in FLAG_CASES])
def test_counts_above_their_budget_are_refused(argv, must, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [str(tmp_path) if a == "{tmp}" else a for a in argv]
    _refused(capsys, argv + ["--out", out], *must)
    assert not out.exists()


def test_parameter_count_matches_torch():
    """The budget's count is the network's: transformer_parameters == the parameters torch allocates."""
    for d, layers, heads, ff in [(32, 1, 2, 48), (64, 3, 4, 128), (48, 2, 6, 16)]:
        net = encoder_stack(d, layers, heads, ff, 0.0)
        assert limits.transformer_parameters(d, layers, ff) == sum(p.numel() for p in net.parameters())


def test_library_configs_check_the_same_budgets():
    with pytest.raises(ValueError, match="MAX_ROOMS"):
        SynthConfig(out="x", rooms=limits.MAX_ROOMS + 1)
    with pytest.raises(ValueError, match="MAX_PARAMETERS"):  # e.g. a checkpoint's config: refused before any weight
        DenoiserConfig(d_model=2**16, heads=16)
    DenoiserConfig(d_model=512, layers=8, heads=16, ff=1024)  # the paper's size is within the budget
    limits.check_batch(256, 10 * 2**20)  # the paper's batch: 256 x ~10 MiB
    with pytest.raises(ValueError, match="MAX_BATCH_BYTES"):
        limits.check_batch(limits.MAX_BATCH, 10 * 2**20)
    assert torch.get_default_dtype() == torch.float32  # the budgets count 4 bytes a value
