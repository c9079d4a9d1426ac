"""Checkpoints: round trip, and clear errors for missing, corrupt, foreign, wrong-kind and inconsistent files."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch

from trumans.model.checkpoint import (FORMAT_VERSION, KINDS, Checkpoint, KindSpec, load_checkpoint, register_kind,
                                      resign_checkpoint, save_checkpoint)
from trumans.model.diffusion import DiffusionConfig
from trumans.model.episodes import Normalizer
from trumans.model.nets import ActionEncoderConfig, Denoiser, DenoiserConfig

torch.set_num_threads(1)


def _ckpt(kind: str = "generator", d_model: int = 32) -> tuple[Checkpoint, Denoiser]:
    torch.manual_seed(0)
    cfg = DenoiserConfig(d_model=d_model, layers=1, heads=4, ff=64,
                         action=ActionEncoderConfig(num_actions=3, d_model=16, layers=1, heads=2, ff=32))
    model = Denoiser(cfg)
    ck = Checkpoint(kind=kind, model_config=cfg, diffusion_config=DiffusionConfig(), model_state=model.state_dict(),
                    normalizer=Normalizer(np.zeros(72), np.ones(72)), vocabulary=["walk", "sit", "reach"], fps=10.0,
                    L_epi=16, k=2, grid={"n": 32, "extent": [1.2, 1.2, 1.2]}, data={"name": "tiny", "hash": "ab"},
                    ema_state=model.state_dict(), train_state={"step": 3, "history": {"train": [0.5, 0.4]}})
    return ck, model


def test_round_trip(tmp_path: Path) -> None:
    ck, model = _ckpt()
    p = tmp_path / "c.pt"
    save_checkpoint(p, ck)
    back = load_checkpoint(p)
    assert back.model_config == ck.model_config and back.vocabulary == ck.vocabulary and back.L_epi == 16
    assert back.grid == ck.grid and back.data["hash"] == "ab" and back.train_state["step"] == 3
    x, t = torch.randn(2, 16, 72), torch.tensor([4, 9])
    a = torch.rand(2, 16, 3)
    with torch.no_grad():
        assert torch.equal(back.build_model()(x, t, actions=a), model.eval()(x, t, actions=a))
    assert not any(f.name.endswith(".tmp") for f in tmp_path.iterdir())  # atomic write leaves no temp file


def test_missing_and_corrupt_files(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_checkpoint(tmp_path / "nope.pt")
    junk = tmp_path / "junk.pt"
    for seed in range(20):
        junk.write_bytes(np.random.default_rng(seed).bytes(2000))
        with pytest.raises(ValueError, match="not a readable trumans checkpoint"):
            load_checkpoint(junk)
    ck, _ = _ckpt()
    good = tmp_path / "good.pt"
    save_checkpoint(good, ck)
    trunc = tmp_path / "trunc.pt"
    raw = good.read_bytes()
    for frac in (0.1, 0.5, 0.9):
        trunc.write_bytes(raw[: int(len(raw) * frac)])
        with pytest.raises(ValueError, match="not a readable trumans checkpoint"):
            load_checkpoint(trunc)
    # altered tensor bytes: torch's zip reader does not notice them, the checkpoint's digest does
    w = ck.model_state["out_proj.weight"].contiguous().numpy().tobytes()
    at = raw.find(w)
    assert at > 0
    flipped = bytearray(raw)
    flipped[at + 8] ^= 0xFF
    trunc.write_bytes(bytes(flipped))
    assert not torch.equal(torch.load(trunc, weights_only=True)["model"]["out_proj.weight"], ck.model_state["out_proj.weight"])
    with pytest.raises(ValueError, match="does not match the digest"):
        load_checkpoint(trunc)
    # anywhere else: a flipped byte is refused, or (zip padding, timestamps) changes nothing that loads
    for pos in range(0, len(raw), max(1, len(raw) // 40)):
        flipped = bytearray(raw)
        flipped[pos] ^= 0xFF
        trunc.write_bytes(bytes(flipped))
        try:
            back = load_checkpoint(trunc)
        except ValueError as e:
            assert "checkpoint" in str(e)
            continue
        assert all(torch.equal(back.model_state[k], v) for k, v in ck.model_state.items()), pos
        assert all(torch.equal(back.ema_state[k], v) for k, v in ck.ema_state.items()), pos
        assert back.vocabulary == ck.vocabulary and np.array_equal(back.normalizer.std, ck.normalizer.std), pos


def test_foreign_files_are_refused(tmp_path: Path) -> None:
    p = tmp_path / "other.pt"
    torch.save({"state_dict": {"w": torch.zeros(2)}}, p)
    with pytest.raises(ValueError, match="not a trumans checkpoint"):
        load_checkpoint(p)

    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    evil = tmp_path / "evil.pt"
    torch.save({"format": "trumans-checkpoint", "x": Evil()}, evil)
    with pytest.raises(ValueError, match="not a readable"):  # weights_only refuses to build arbitrary objects
        load_checkpoint(evil)


def test_wrong_kind_version_and_inconsistent(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setitem(KINDS, "filter", KINDS["generator"])  # a filter built like the generator, for this test
    ck, _ = _ckpt(kind="filter")
    p = tmp_path / "f.pt"
    save_checkpoint(p, ck)
    with pytest.raises(ValueError, match="'filter' checkpoint"):
        load_checkpoint(p)
    assert load_checkpoint(p, kind=None).kind == "filter"

    d = torch.load(p, weights_only=True)
    d["format_version"] = FORMAT_VERSION + 1
    torch.save(d, p)
    with pytest.raises(ValueError, match="newer"):
        load_checkpoint(p, kind=None)

    ck, _ = _ckpt()
    other, _ = _ckpt(d_model=64)
    ck.model_state = other.model_state  # weights of another size
    ck.ema_state = None
    save_checkpoint(p, ck)
    with pytest.raises(ValueError, match="do not match its model config"):
        load_checkpoint(p).build_model()

    ck, _ = _ckpt()
    ck.vocabulary = ["walk"]
    save_checkpoint(p, ck)
    with pytest.raises(ValueError, match="vocabulary"):
        load_checkpoint(p)

    d = torch.load(p, weights_only=True)
    del d["norm"], d["digest"]  # as an older writer would have left it
    torch.save(d, p)
    with pytest.raises(ValueError, match="has no digest.*python -m trumans.model.checkpoint"):
        load_checkpoint(p)
    resign_checkpoint(p)  # its owner trusts it: signed, it loads as far as its missing field
    with pytest.raises(ValueError, match="lacks"):
        load_checkpoint(p)


def test_kinds_registry_required_fields_and_old_files(tmp_path: Path, monkeypatch) -> None:
    from dataclasses import asdict, dataclass

    @dataclass(frozen=True)
    class TinyConfig:
        width: int = 4

        def to_dict(self) -> dict:
            return asdict(self)

    def check(c: Checkpoint) -> None:
        if c.extra["classes"] != 2:
            raise ValueError(f"classes must be 2, got {c.extra['classes']}")

    p = tmp_path / "c.pt"
    torch.manual_seed(0)
    lin = torch.nn.Linear(4, 2)
    contact = Checkpoint(kind="contact", model_config=TinyConfig(), model_state=lin.state_dict(), fps=30.0,
                         extra={"classes": 2})
    monkeypatch.delitem(KINDS, "contact", raising=False)  # the table names trumans.track.model_io.CONTACT_KIND
    with pytest.raises(ValueError, match="no model builder is registered for 'contact'"):
        save_checkpoint(p, contact)
    monkeypatch.setitem(KINDS, "contact", KindSpec(config_from_dict=lambda d: TinyConfig(**d),
                                                   build=lambda c: torch.nn.Linear(c.width, 2),
                                                   required=("fps",), required_extra=("classes",), check=check))
    save_checkpoint(p, contact)
    back = load_checkpoint(p, kind="contact")
    assert back.model_config == TinyConfig() and back.normalizer is None and back.vocabulary is None and back.fps == 30.0
    x = torch.randn(3, 4)
    assert torch.equal(back.build_model()(x), lin(x))
    with pytest.raises(ValueError, match="'contact' checkpoint, but a 'generator'"):
        load_checkpoint(p)
    with pytest.raises(ValueError, match="no diffusion config"):
        back.build_diffusion()
    with pytest.raises(ValueError, match=r"without \['extra.classes'\]"):
        save_checkpoint(p, Checkpoint(kind="contact", model_config=TinyConfig(), model_state=lin.state_dict(), fps=30.0))
    d = torch.load(p, weights_only=True)
    d["extra"]["classes"] = 3
    del d["digest"]  # a file written before digests: refused until its owner signs it
    torch.save(d, p)
    with pytest.raises(ValueError, match="has no digest"):
        load_checkpoint(p, kind="contact")
    resign_checkpoint(p)  # signed, the kind's check still runs
    with pytest.raises(ValueError, match="classes must be 2"):
        load_checkpoint(p, kind="contact")
    with pytest.raises(ValueError, match="kind must be one of"):
        register_kind("tracker", KINDS["contact"])
    # a generator without the generator's fields cannot be saved
    ck, _ = _ckpt()
    ck.normalizer = None
    with pytest.raises(ValueError, match="norm"):
        save_checkpoint(p, ck)
    # files from before kinds were typed (no "kind", no "digest", no "extra") load as generators
    ck, model = _ckpt()
    save_checkpoint(p, ck)
    d = torch.load(p, weights_only=True)
    for key in ("kind", "digest", "extra"):
        del d[key]
    torch.save(d, p)
    resign_checkpoint(p)
    old = load_checkpoint(p)
    assert old.kind == "generator" and old.extra == {} and old.L_epi == 16
    d["kind"] = "tracker"
    torch.save(d, p)
    resign_checkpoint(p)
    with pytest.raises(ValueError, match="unknown checkpoint kind 'tracker'"):
        load_checkpoint(p, kind=None)


def test_non_finite_weights_are_refused(tmp_path: Path) -> None:
    ck, _ = _ckpt()
    ck.ema_state = {k: v.clone() for k, v in ck.ema_state.items()}
    ck.ema_state["out_proj.bias"][0] = float("nan")
    p = tmp_path / "nan.pt"
    save_checkpoint(p, ck)
    with pytest.raises(ValueError, match=r"non-finite \(NaN or inf\) ema weights in \['out_proj.bias'\]"):
        load_checkpoint(p)


def test_resign_command_signs_a_trusted_file_and_refuses_foreign_ones(tmp_path: Path) -> None:
    from trumans.model.checkpoint import main

    ck, _ = _ckpt()
    p = tmp_path / "old.pt"
    save_checkpoint(p, ck)
    d = torch.load(p, weights_only=True)
    del d["digest"]
    torch.save(d, p)
    assert main([str(p), "--out", str(tmp_path / "signed.pt")]) == 0
    assert load_checkpoint(tmp_path / "signed.pt").L_epi == ck.L_epi
    torch.save({"weights": torch.zeros(2)}, tmp_path / "foreign.pt")
    assert main([str(tmp_path / "foreign.pt")]) == 2
    assert main([str(tmp_path / "missing.pt")]) == 2
