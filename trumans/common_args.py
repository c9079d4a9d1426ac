"""Flags with one meaning on every command (docs/conventions.md "Command behaviour").

- ``--device DEV``: the torch device of a command that runs a network (``cpu``, ``cuda``, ``cuda:N``;
  checked by ``trumans.argtypes.device``); ``add_device_argument``.
- ``--no-progress``: hide the progress bar (on stderr) of a command that prints one; ``add_no_progress_argument``.
- ``--out``: what is written, said the same way in every help: ``out_help('folder' | 'file' | 'stem', ...)``.
- ``--formats``: the output formats (comma-separated); the input layout of ``data import`` is ``--input-format``.
- ``--steps``: denoising steps (sample, refine, eval); training's optimiser steps are ``--max-steps``.
- Renamed flags keep their old spelling as a hidden alias (``add_hidden_alias``).
``--checkpoint`` and ``--threads``: ``trumans.checkpoint_args``, ``trumans.threads``; ``--shard``: ``trumans.shards``.
"""
from __future__ import annotations

import argparse

__all__ = ["add_device_argument", "add_no_progress_argument", "out_help", "add_hidden_alias"]


def add_device_argument(p: argparse.ArgumentParser, default: str | None = "cpu", runs: str | None = None) -> None:
    """``--device`` (``cpu``, ``cuda``, ``cuda:N``); ``default`` None = cuda if this machine has it, else cpu.
    ``runs``: what runs on the device when it is not the whole job (said in the help, e.g. "the contact
    predictor; the rest of the tracker is numpy on the CPU")."""
    from trumans import argtypes

    shown = "cuda if available, else cpu" if default is None else default
    where = f"; runs there: {runs}" if runs else ""
    p.add_argument("--device", type=argtypes.device, default=default, metavar="DEV",
                   help=f"torch device: cpu, cuda or cuda:N (default {shown}){where}")


def add_no_progress_argument(p: argparse.ArgumentParser) -> None:
    """``--no-progress``: no progress bar on stderr (``args.no_progress``)."""
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar (stderr)")


def out_help(kind: str, what: str) -> str:
    """The help of an ``--out`` flag: ``kind`` is 'folder', 'file' or 'stem' (a path without extension, one
    file per format written beside it), ``what`` says what it holds."""
    lead = {"folder": "output folder", "file": "output file", "stem": "output path stem (no extension)"}
    if kind not in lead:
        raise ValueError(f"out kind must be folder, file or stem, got {kind!r}")
    return f"{lead[kind]}: {what}"


def add_hidden_alias(p: argparse.ArgumentParser, old: str, dest: str, **kwargs) -> None:
    """Accept the older spelling ``old`` of a renamed flag, writing the same ``dest``, without showing it in
    ``--help`` (command lines written before the rename keep working)."""
    p.add_argument(old, dest=dest, help=argparse.SUPPRESS, default=argparse.SUPPRESS, **kwargs)
