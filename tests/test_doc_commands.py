"""Every `trumans ...` command in the README's and docs/*.md's code blocks parses with the real parser
(issue 37 point 7: the README examples all run), and the cheap ones run for real.

Run for real (seconds each, in a scratch folder holding the shipped examples/): `--help`,
`trumans scene inspect examples/...`, `trumans view examples/... --html ...`. Only parsed: everything
else, because it needs data the test does not have (a built dataset, `out/*.npz` from an earlier
command, the user's own files) or runs for minutes (data synth, augment, train, sample, the eval
benchmarks); what each of those does is tested by its own test module. Lines whose words are usage
synopses (`[CHECKPOINT]`, `[--plans 12]`) are not commands and are skipped (listed in ``SYNOPSIS``).
"""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from trumans.cli import build_parser, console_main

from helpers import REPO_ROOT

DOCS = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
_BLOCK = re.compile(r"(?ms)^```[^\n]*\n(.*?)^```")
_START = re.compile(r"(?:^|[;&|]\s*|\bdo\s+|\bthen\s+)(?:[A-Z_]+=\S*\s+)*(trumans\s.*)$")
_SHELL_OPS = {"&", "&&", ";", "|", "||", ">", ">>", "2>", "2>&1"}
_VAR = re.compile(r"\$\{?[A-Za-z_][A-Za-z0-9_]*\}?")


def doc_commands() -> list[tuple[str, list[str]]]:
    """``(where, argv)`` of every `trumans ...` line in a code block (after ``trumans``); shell variables
    stand for 1 (a Slurm task id, a loop counter), comments and what follows a shell operator are dropped."""
    found = []
    for path in DOCS:
        for m in _BLOCK.finditer(path.read_text()):
            for line in m.group(1).replace("\\\n", " ").splitlines():
                hit = _START.search(line.strip().removeprefix("$ "))
                if not hit:
                    continue
                words = shlex.split(_VAR.sub("1", hit.group(1)), comments=True)
                cut = next((i for i, w in enumerate(words) if w in _SHELL_OPS), len(words))
                found.append((f"{path.relative_to(REPO_ROOT)}: {hit.group(1)[:90]}", words[1:cut]))
    return found


COMMANDS = doc_commands()
SYNOPSIS = [(w, a) for w, a in COMMANDS if any(x.startswith("[") for x in a)]
RUNNABLE = [(w, a) for w, a in COMMANDS if (w, a) not in SYNOPSIS]


def _cheap(argv: list[str]) -> bool:
    """Runs in seconds with what ships: help, scene inspect of an example mesh, the HTML view of examples."""
    if "--help" in argv or "-h" in argv:
        return True
    if argv[:2] == ["scene", "inspect"]:
        return argv[2].startswith("examples/")
    if argv[:1] == ["view"] and "--html" in argv:
        seqs = [a for a in argv[1:argv.index("--html")] if not a.startswith("-")]
        return bool(seqs) and all(a.startswith("examples/") for a in seqs)
    return False


def test_the_docs_hold_commands():
    assert len(RUNNABLE) > 60 and len(SYNOPSIS) <= 4
    assert sum(_cheap(a) for _, a in RUNNABLE) >= 2


@pytest.mark.parametrize("where, argv", RUNNABLE, ids=[w for w, _ in RUNNABLE])
def test_doc_command_parses(where, argv):
    try:
        args = build_parser(argv).parse_args(argv)
    except SystemExit as e:  # --help
        assert e.code == 0, where
        return
    assert hasattr(args, "_run"), where


@pytest.mark.parametrize("where, argv", [(w, a) for w, a in RUNNABLE if _cheap(a)],
                         ids=[w for w, a in RUNNABLE if _cheap(a)])
def test_cheap_doc_command_runs(where, argv, tmp_path, monkeypatch, capsys):
    (tmp_path / "examples").symlink_to(REPO_ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    try:
        assert console_main(argv) == 0, capsys.readouterr().err
    except SystemExit as e:
        assert e.code == 0
