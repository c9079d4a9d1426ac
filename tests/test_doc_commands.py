"""Every `trumans ...` command in the README's and docs/*.md's code blocks, and every example in a command's
own ``--help`` (a help line that starts with ``trumans ``, or a backticked ``trumans ... --flag`` span without
``...``), parses with the real parser (issue 37 point 7: the README examples all run), and the cheap ones run
for real. The plans of the ``trumans sample`` examples whose scene ships (default, room:SEED, examples/...)
compile in their scene as ``trumans sample`` compiles them before sampling: every goto is on walkable floor,
every named object exists and has what the step needs (``plan_check``).

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

from functools import lru_cache

import numpy as np
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


def _help_text(path: tuple[str, ...]) -> str:
    """What ``trumans PATH --help`` prints (the command's own parser)."""
    sub = build_parser(list(path))
    for word in path:
        sub = next(a for a in sub._actions if a.__class__.__name__ == "_SubParsersAction").choices[word]
    return sub.format_help()


def help_commands() -> list[tuple[str, list[str]]]:
    """``(where, argv)`` of every example in every command's ``--help``: its lines that start with
    ``trumans `` (the examples of a description or epilog) and backticked ``trumans ... --flag`` spans
    (a flag named inline) without a ``...`` placeholder."""
    from trumans.cli import COMMANDS as CLI_COMMANDS

    found = []
    for path, _, _ in CLI_COMMANDS:
        text = _help_text(path)
        where = f"trumans {' '.join(path)} --help"
        for line in text.splitlines():
            hit = _START.search(line.strip().removeprefix("$ "))
            if hit:
                words = shlex.split(hit.group(1), comments=True)
                found.append((f"{where}: {hit.group(1)[:80]}", words[1:]))
        for m in re.finditer(r"`(trumans [^`]*--[^`]*)`", " ".join(text.split())):
            if "..." not in m.group(1):
                found.append((f"{where}: `{m.group(1)[:80]}`", shlex.split(m.group(1))[1:]))
    return found


HELP_COMMANDS = help_commands()
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


def test_the_helps_hold_examples():
    """The sample help's examples are found (a help that loses them would pass the tests below vacuously)."""
    sample = [a for w, a in HELP_COMMANDS if a[:1] == ["sample"]]
    assert len(sample) >= 4 and any("--goto" in a for a in sample)


@pytest.mark.parametrize("where, argv", HELP_COMMANDS, ids=[w for w, _ in HELP_COMMANDS])
def test_help_example_parses(where, argv):
    assert not any(x.startswith("[") for x in argv), f"{where}: a synopsis, not an example"
    test_doc_command_parses(where, argv)


@pytest.mark.parametrize("where, argv", [(w, a) for w, a in HELP_COMMANDS if _cheap(a)],
                         ids=[w for w, a in HELP_COMMANDS if _cheap(a)])
def test_cheap_help_example_runs(where, argv, tmp_path, monkeypatch, capsys):
    test_cheap_doc_command_runs(where, argv, tmp_path, monkeypatch, capsys)


_SHIPPED_SCENE = re.compile(r"^(default|room:\d+|examples/.*)$")


def _plan_checkable(argv: list[str]) -> bool:
    """A `trumans sample` example whose scene, plan file and body ship (or are built in)."""
    if argv[:1] != ["sample"]:
        return False
    for flag in ("--plan", "--body"):
        if flag in argv and not argv[argv.index(flag) + 1].startswith("examples/"):
            return False
    return bool(_SHIPPED_SCENE.match(argv[argv.index("--scene") + 1] if "--scene" in argv else "default"))


@lru_cache(maxsize=4)
def _sample_scene(spec: str, up: str):
    from trumans.sample.scene_input import load_sample_scene

    return load_sample_scene(spec, up=up)


def plan_check(argv: list[str]) -> int:
    """What ``trumans sample ARGV`` checks before it samples, without sampling: the plan (file, step flags or
    the default plan) resolved and validated in the scene and compiled into phases from its start
    (``trumans.sample.generate.generate_sequences`` up to ``sample_plan``; ``compile_plan`` refuses a goto
    off the walkable floor). Raises ValueError naming the step; returns the number of phases."""
    from trumans.model.checkpoint import load_checkpoint
    from trumans.sample.cli import steps_from_flags
    from trumans.sample.controller import compile_plan
    from trumans.sample.generate import DEFAULT_CHECKPOINT, check_points_inside, resolve_plan
    from trumans.sample.plan import plan_from_dict, validate_plan
    from trumans.sample.rollout import action_seconds

    args = build_parser(argv).parse_args(argv)
    flags = list(getattr(args, "plan_steps", None) or [])
    plan = args.plan or (plan_from_dict({"steps": steps_from_flags(flags)}, name="flags") if flags else None)
    sc = _sample_scene(args.scene, args.up)
    the_plan = resolve_plan(plan, sc)
    start = None if args.start is None else tuple(float(v) for v in args.start.split(","))
    check_points_inside(the_plan, sc.scene, start)
    ckpt = load_checkpoint(args.checkpoint or DEFAULT_CHECKPOINT, kind="generator")
    validate_plan(the_plan, sc.scene, ckpt.vocabulary)
    xy = np.asarray(start or the_plan.start or sc.free_point(), np.float64)
    if not sc.walkmap.query(xy[None])[0]:
        raise ValueError(f"start {xy.tolist()} is not on walkable floor")
    heading = args.heading if args.heading is not None else (the_plan.heading or 0.0)
    return len(compile_plan(the_plan, sc.scene, sc.walkmap, xy, action_seconds(ckpt), ckpt.fps,
                            vocabulary=ckpt.vocabulary, heading=float(heading)))


SAMPLE_EXAMPLES = [(w, a) for w, a in HELP_COMMANDS + RUNNABLE if _plan_checkable(a)]


def test_plan_check_refuses_an_unwalkable_goto():
    """The check is not vacuous: the help's old example (--goto 1,1: inside the default room's table) fails."""
    with pytest.raises(ValueError, match="not on walkable floor"):
        plan_check(["sample", "--goto", "2.0,1.5", "--goto", "1,1", "--out", "out/y"])


@pytest.mark.parametrize("where, argv", SAMPLE_EXAMPLES, ids=[w for w, _ in SAMPLE_EXAMPLES])
def test_sample_example_plan_compiles(where, argv, monkeypatch):
    monkeypatch.chdir(REPO_ROOT)  # examples/... as the docs write them
    assert plan_check(argv) >= 1, where


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
