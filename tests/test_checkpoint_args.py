"""``--checkpoint`` names the checkpoint on every command; the eval commands keep the positional form."""
from __future__ import annotations

import pytest

from trumans.cli import build_parser, console_main


@pytest.mark.parametrize("argv, msg", [
    (["eval", "train", "--checkpoint", "missing.pt"], "does not exist"),
    (["eval", "train", "missing.pt"], "does not exist"),
    (["eval", "train", "a.pt", "--checkpoint", "b.pt"], "given twice"),
    (["eval", "train"], "--checkpoint"),
    (["eval", "contacts", "x.pt", "--checkpoint", "y.pt"], "given twice"),
    (["eval", "synthesis", "x.pt", "--checkpoint", "y.pt"], "given twice"),
    (["eval", "refine", "x.pt", "--checkpoint", "y.pt"], "given twice"),
    (["eval", "synthesis", "--checkpoint", "missing.pt", "--rooms", "1"], "does not exist"),
    (["eval", "refine", "--checkpoint", "missing.pt"], "does not exist"),
])
def test_checkpoint_flag_and_positional(argv, msg, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert console_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("trumans: error:") and msg in err[0], err


def test_every_checkpoint_loading_command_has_the_flag():
    for cmd in (["sample"], ["refine"], ["eval", "train"], ["eval", "contacts"], ["eval", "synthesis"], ["eval", "refine"]):
        p = build_parser(cmd)
        sub = p
        for w in cmd:
            sub = next(a for a in sub._actions if a.__class__.__name__ == "_SubParsersAction").choices[w]
        assert any("--checkpoint" in a.option_strings for a in sub._actions), cmd
