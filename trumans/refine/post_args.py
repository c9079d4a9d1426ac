"""Command-line switches of the HOI filter's post-steps, shared by ``trumans refine`` and ``trumans
eval refine``.

Generated from the step table (``trumans.refine.post_steps.STEPS``): ``--no-<flag>`` turns a step
off (``--no-drift-correction``, ``--no-foot-lock``, ``--no-rest-pooling``, ``--no-hinge``), a
sub-switch of a step's config has its own (``--no-hand-link``), a step's ``force`` field is
``--<flag>`` (``--hinge``: whatever the category), and ``--set PATH=VALUE`` reaches any other
parameter (``--set post.body_drift.speed_m_s=0.25``). Every default comes from ``PostStepsConfig``.
"""
from __future__ import annotations

import argparse

from trumans.config_data import set_entries
from trumans.refine.post_steps import STEPS, PostStepsConfig

__all__ = ["add_post_step_arguments", "post_steps_config"]

SET_ROOTS = ("post",)  # the section --set reaches: the post-steps' config (RefineOptions.post)


def add_post_step_arguments(p: argparse.ArgumentParser) -> None:
    """One ``--no-<flag>`` per post-step and sub-switch, ``--<flag>`` for a step's ``force`` and ``--set``."""
    g = p.add_argument_group("post-steps after the filter (all on by default; trumans/refine/post_steps.py)")
    for step in STEPS:
        off = dict(dest=f"post_{step.name}", action="store_false", help=f"post-step '{step.name}' off: do not {step.does}")
        if step.force is None:
            g.add_argument(f"--no-{step.flag}", **off)
        else:
            both = g.add_mutually_exclusive_group()
            both.add_argument(f"--{step.flag}", dest=f"post_{step.name}_{step.force}", action="store_true",
                              help=step.force_help)
            both.add_argument(f"--no-{step.flag}", **off)
        for sub in step.subs:
            g.add_argument(f"--no-{sub.flag}", dest=f"post_{step.name}_{sub.field}", action="store_false",
                           help=f"{step.name}.{sub.field} off: do not {sub.does}")
    g.add_argument("--set", dest="post_set", action="append", default=[], metavar="PATH=VALUE",
                   help="set any parameter of a post-step by its path, VALUE as JSON, e.g. "
                        "--set post.body_drift.speed_m_s=0.25 --set post.hinge.categories='[\"door\", \"drawer\"]' "
                        "(repeatable; the paths: PostStepsConfig in trumans/refine/post_steps.py)")


def _overrides(args: argparse.Namespace) -> dict:
    """The ``{'post': ...}`` dict of a ``PostStepsConfig`` set by the switches and ``--set``."""
    post: dict = {}
    for step in STEPS:
        d = post[step.name] = {"enabled": bool(getattr(args, f"post_{step.name}"))}
        if step.force is not None and getattr(args, f"post_{step.name}_{step.force}"):
            d[step.force] = True
        for sub in step.subs:
            d[sub.field] = bool(getattr(args, f"post_{step.name}_{sub.field}"))
    return set_entries({"post": post}, getattr(args, "post_set", None) or [], SET_ROOTS,
                       "post.body_drift.speed_m_s=0.25")


def post_steps_config(args: argparse.Namespace) -> PostStepsConfig:
    """The ``PostStepsConfig`` of a command line with the arguments above."""
    return PostStepsConfig.from_dict(_overrides(args)["post"], where="post")
