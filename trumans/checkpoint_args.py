"""``--checkpoint``: one flag naming the checkpoint on every command that loads one.

``trumans sample`` and ``trumans refine`` take ``--checkpoint PATH``; the ``eval`` commands take the same
flag and, as before, the checkpoint as a positional argument (kept so existing command lines work; giving
both is an error). ``track`` and ``eval contacts`` take one contact model or one per
degree-of-freedom class (``--checkpoint DOF=PATH``, repeatable).
"""
from __future__ import annotations

import argparse

__all__ = ["add_checkpoint_arguments", "resolve_checkpoint"]

_POSITIONAL = "checkpoint_positional"


def add_checkpoint_arguments(p: argparse.ArgumentParser, help: str, many: bool = False,
                             metavar: str = "CHECKPOINT") -> None:
    """``--checkpoint`` (repeatable when ``many``) plus the older positional form; call
    ``resolve_checkpoint(args)`` in ``run`` before using ``args.checkpoint``."""
    if many:
        p.add_argument(_POSITIONAL, nargs="*", default=[], metavar=metavar, help=f"{help} (or --checkpoint)")
        p.add_argument("--checkpoint", action="append", default=[], metavar=metavar, help=f"{help}; repeatable")
    else:
        p.add_argument(_POSITIONAL, nargs="?", default=None, metavar=metavar, help=f"{help} (or --checkpoint)")
        p.add_argument("--checkpoint", default=None, metavar=metavar, help=help)


def resolve_checkpoint(args: argparse.Namespace):
    """Merge the positional form into ``args.checkpoint`` (None / [] = the command's default); giving both
    forms is a ValueError naming the fix. Returns ``args.checkpoint``."""
    pos, flag = getattr(args, _POSITIONAL, None), getattr(args, "checkpoint", None)
    if pos and flag:
        raise ValueError(f"the checkpoint is given twice ({pos} and --checkpoint {flag}); give it once, "
                         f"as --checkpoint")
    if pos:
        args.checkpoint = pos
    return args.checkpoint
