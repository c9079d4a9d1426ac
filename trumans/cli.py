"""The ``trumans`` console script: one subcommand per job (docs/conventions.md "Command behaviour").

Each subcommand lives in the package that owns it, as a module with
``add_arguments(parser: argparse.ArgumentParser) -> None`` and ``run(args) -> int``; ``COMMANDS``
is the one table of them. Only the module of the command being run is imported (``trumans --help``
and a group's help import none), so ``import trumans`` never imports the jobs and a command does
not pay for the others' imports.

Errors (``console_main``), one channel for every command:
- expected failures (bad arguments, missing or corrupt files, bad values, a locked output folder,
  disk errors): one line ``trumans: error: <what is wrong and how to fix it>``, exit status 2;
- anything else is a bug: one line ``trumans: error: unexpected <Type>: <message>; this is a bug,
  run with TRUMANS_DEBUG=1 and report it``, exit status 1;
- Ctrl-C: ``trumans: interrupted``, exit status 130.
``TRUMANS_DEBUG=1`` re-raises instead (full traceback).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

# (command path, module, one-line help)
COMMANDS: list[tuple[tuple[str, ...], str, str]] = [
    (("data", "synth"), "trumans.synth.cli", "build the embedded synthetic HSI dataset"),
    (("data", "import"), "trumans.importers.cli", "import TRUMANS-release, BVH or FBX data into the dataset format"),
    (("data", "merge"), "trumans.shards", "merge the shard folders of a `--shard K/N` build into one dataset"),
    (("augment",), "trumans.augment.cli", "contact-preserving CCD-IK augmentation of a dataset"),
    (("train",), "trumans.train.cli", "train the generator (or filter / contact model) from a config"),
    (("sample",), "trumans.sample.cli", "sample a long motion in a scene from a plan"),
    (("refine",), "trumans.refine.cli", "refine a tracked HOI sequence with the diffusion filter"),
    (("track",), "trumans.track.cli", "contact-driven interaction tracking of a body in a scene (iReplica)"),
    (("view",), "trumans.viz.cli", "render a sequence to GIF/MP4 and a top-down PNG"),
    (("scene", "inspect"), "trumans.scenes.inspect_cli", "list the seats, beds and tables found in a mesh or scene folder"),
    (("eval", "synthesis"), "trumans.sample.eval_synthesis", "synthesis benchmark figures"),
    (("eval", "safety"), "trumans.sample.eval_safety", "worst-case scene-safety benchmark under perturbations"),
    (("eval", "augment"), "trumans.augment.evaluate", "augmentation benchmark figures"),
    (("eval", "train"), "trumans.train.evaluate", "recompute a checkpoint's validation loss"),
    (("eval", "refine"), "trumans.refine.evaluate", "HOI-filter benchmark figures"),
    (("eval", "contacts"), "trumans.track.evaluate", "contact-prediction benchmark figures"),
    (("eval", "realism"), "trumans.eval.realism_cli", "realism statistics of a dataset against real mocap"),
    (("eval", "local-query"), "trumans.scenes.bench_local_query", "local occupancy query benchmark"),
]


class UsageError(ValueError):
    """A command line that argparse rejects (unknown option, bad value, missing argument)."""


class _Parser(argparse.ArgumentParser):
    """argparse, but a bad command line raises ``UsageError`` (printed by ``console_main`` as
    one ``trumans: error:`` line) instead of printing usage and exiting."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(f"{message} (see `{self.prog} --help`)")


def _selected(argv: list[str] | None) -> tuple[str, ...] | None:
    """The command path that ``argv`` names (its leading words), () for none, None to load every one."""
    if argv is None:
        return None
    words = []
    for a in argv:
        if a.startswith("-"):
            break
        words.append(a)
    best: tuple[str, ...] = ()
    for path, _, _ in COMMANDS:
        if tuple(words[:len(path)]) == path and len(path) > len(best):
            best = path
    return best


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The parser of every command; with ``argv``, only the named command's module is imported
    (the others are listed with their one-line help)."""
    selected = _selected(argv)
    parser = _Parser(prog="trumans", description="Human-scene interaction motion framework.")
    from .version import __version__

    parser.add_argument("--version", action="version", version=f"trumans {__version__}")
    groups: dict[tuple[str, ...], argparse._SubParsersAction] = {(): parser.add_subparsers(dest="command", metavar="COMMAND")}
    group_parsers: dict[tuple[str, ...], argparse.ArgumentParser] = {}
    for path, module, help_ in COMMANDS:
        for depth in range(1, len(path)):
            key = path[:depth]
            if key not in groups:
                gp = groups[path[:depth - 1]].add_parser(key[-1], help=f"{key[-1]} subcommands")
                group_parsers[key] = gp
                groups[key] = gp.add_subparsers(dest="_".join(key) + "_command", metavar="SUBCOMMAND")
        sub = groups[path[:-1]].add_parser(path[-1], help=help_, description=help_)
        if selected is None or selected == path:
            mod = importlib.import_module(module)
            mod.add_arguments(sub)
            sub.set_defaults(_run=mod.run)
    for key, gp in group_parsers.items():
        gp.set_defaults(_run=_usage(gp))
    parser.set_defaults(_run=_usage(parser))
    return parser


def _usage(p: argparse.ArgumentParser):
    def run(args) -> int:
        p.print_help(sys.stderr)
        print(f"trumans: error: `{p.prog}` needs a command; choose one of those listed above", file=sys.stderr)
        return 2
    return run


def _older_spellings(argv: list[str]) -> list[str]:
    """``refine X --interactions ...`` -> ``track X ...`` (the tracker was a mode of refine)."""
    if argv[:1] == ["refine"] and "--interactions" in argv and "-h" not in argv and "--help" not in argv:
        return ["track"] + [a for a in argv[1:] if a != "--interactions"]
    return argv


def main(argv: list[str] | None = None) -> int:
    argv = _older_spellings(sys.argv[1:] if argv is None else list(argv))
    args = build_parser(argv).parse_args(argv)
    out = getattr(args, "out", None)
    if isinstance(out, str) and not out.strip():  # every command: `--out "$UNSET"` never means "here"
        raise UsageError("--out is empty (an unset shell variable?); give the output path")
    return int(args._run(args) or 0)


def _expected() -> tuple[type[BaseException], ...]:
    from .io_lock import FolderLocked

    # ValueError covers bad values, UsageError, JSON and Unicode decoding; OSError covers missing /
    # unreadable files, full disks and permissions
    return (ValueError, OSError, FolderLocked)


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text


def console_main(argv: list[str] | None = None) -> int:
    """The console script: ``main`` with every failure printed as one ``trumans: error:`` line
    (module doc): exit status 2 for bad input, 1 for a bug, 130 for Ctrl-C. TRUMANS_DEBUG=1 shows
    the traceback instead. ``main`` itself lets exceptions propagate (for callers and tests)."""
    try:
        return main(argv)
    except KeyboardInterrupt:
        if os.environ.get("TRUMANS_DEBUG"):
            raise
        print("trumans: interrupted (an interrupted build or augmentation resumes when re-run)", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - the one error channel
        if os.environ.get("TRUMANS_DEBUG"):
            raise
        if isinstance(e, _expected()):
            print(f"trumans: error: {_one_line(e)}", file=sys.stderr)
            return 2
        print(f"trumans: error: unexpected {type(e).__name__}: {_one_line(e)}; this is a bug, "
              f"run with TRUMANS_DEBUG=1 and report it", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(console_main())
