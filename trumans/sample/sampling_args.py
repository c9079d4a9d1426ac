"""Command-line switches of the sampler, shared by ``trumans sample`` and ``trumans eval synthesis``.

Every default comes from ``SamplerConfig`` (one place). The switches of the guidance terms and of
the cleanup steps are generated from their tables (``trumans.sample.guidance.terms.TERMS``,
``trumans.sample.cleanup.pipeline.STEPS``): ``--no-<flag>`` turns one off (``--no-seat-guidance``,
``--no-foot-cleanup``, ...), a step's ``option`` is ``--<flag> VALUE`` (``--seam-blend FRAMES``), and
``--set PATH=VALUE`` reaches any other parameter (``--set cleanup.foot.blend=4``).
"""
from __future__ import annotations

import argparse

from trumans.config_data import set_entries

__all__ = ["add_guidance_arguments", "add_postprocess_arguments", "postprocess_kwargs", "sampler_config"]

SET_ROOTS = ("guidance", "cleanup")  # the sections --set reaches; the sampler's other fields have their own flags


def add_guidance_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    p.add_argument("--goal-guidance", type=float, default=d.goal_guidance,
                   help="step size of the spatial guidance pulling the body onto each episode's goal (and the other "
                        f"guidance terms; 0 = inpainting only; default {d.goal_guidance:g})")
    p.add_argument("--goal-iters", type=int, default=d.goal_iters,
                   help=f"guidance updates per denoising step, each a backward pass (default {d.goal_iters})")
    p.add_argument("--overlap", type=int, default=d.overlap, metavar="FRAMES",
                   help="regenerate the last FRAMES new frames of each episode in the next one and crossfade "
                        f"the two (smoother seams, more episodes; default {d.overlap}: none)")
    p.add_argument("--guided-steps", type=int, default=d.guided_steps, metavar="N",
                   help="guide only the last N denoising steps, the earlier ones are plain (0 = every step; "
                        f"default {d.guided_steps})")
    p.add_argument("--guidance-space", choices=("xt", "x0"), default=d.guidance_space,
                   help="guide through the network w.r.t. x_t (a backward pass per update) or on the predicted x0 "
                        f"(no backward pass; default {d.guidance_space})")
    p.add_argument("--x0-guidance", type=float, default=d.x0_guidance, metavar="SCALE",
                   help=f"step-size factor of x0-space guidance (default {d.x0_guidance:g})")
    p.add_argument("--guidance", type=float, nargs=2, default=(d.scene_scale, d.action_scale),
                   metavar=("SCENE", "ACTION"),
                   help="classifier-free guidance scales of the scene and action conditions (1 = plain conditional; "
                        f"default {d.scene_scale:g} {d.action_scale:g})")


def add_postprocess_arguments(p: argparse.ArgumentParser) -> None:
    """One ``--no-<flag>`` per guidance term and cleanup step, the steps' options and ``--set``."""
    from trumans.sample.cleanup.pipeline import STEPS
    from trumans.sample.guidance.terms import TERMS
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    g = p.add_argument_group("guidance terms and post-network cleanup (all on by default; "
                             "trumans/sample/guidance, trumans/sample/cleanup/pipeline.py)")
    for term in TERMS:
        g.add_argument(f"--no-{term.flag}", dest=f"guidance_{term.name}", action="store_false",
                       help=f"guidance term '{term.name}' off: do not {term.does}")
    for step in STEPS:
        g.add_argument(f"--no-{step.flag}", dest=f"cleanup_{step.name}", action="store_false",
                       help=f"cleanup step '{step.name}' off: do not {step.does}")
        if step.option is not None:
            default = getattr(getattr(d.cleanup, step.name), step.option)
            g.add_argument(f"--{step.flag}", dest=f"cleanup_{step.name}_{step.option}", type=type(default),
                           default=default, metavar=step.option.upper(), help=f"{step.option_help} (default {default})")
    g.add_argument("--set", dest="config_set", action="append", default=[], metavar="PATH=VALUE",
                   help="set any parameter of a guidance term or cleanup step by its path, VALUE as JSON, e.g. "
                        "--set cleanup.foot.blend=4 --set guidance.seat.weight=2 (repeatable; the paths: the "
                        "'guidance' and 'cleanup' entries of the sampler config saved in every sampled npz)")


def _overrides(args: argparse.Namespace) -> dict:
    """The ``guidance`` / ``cleanup`` entries of a ``SamplerConfig`` dict set by the switches and ``--set``."""
    from trumans.sample.cleanup.pipeline import STEPS
    from trumans.sample.guidance.terms import TERMS

    d: dict = {"guidance": {t.name: {"enabled": bool(getattr(args, f"guidance_{t.name}"))} for t in TERMS},
               "cleanup": {s.name: {"enabled": bool(getattr(args, f"cleanup_{s.name}"))} for s in STEPS}}
    for s in STEPS:
        if s.option is not None:
            d["cleanup"][s.name][s.option] = getattr(args, f"cleanup_{s.name}_{s.option}")
    return set_entries(d, getattr(args, "config_set", None) or [], SET_ROOTS, "cleanup.foot.blend=4")


def postprocess_kwargs(args: argparse.Namespace) -> dict:
    """The ``SamplerConfig`` fields set by the switches above: {'guidance': GuidanceConfig, 'cleanup': CleanupConfig}."""
    from trumans.sample.sampler import SamplerConfig

    c = SamplerConfig.from_dict(_overrides(args), where="config")
    return {"guidance": c.guidance, "cleanup": c.cleanup}


def sampler_config(args: argparse.Namespace):
    """The ``SamplerConfig`` of a command line with ``--steps``, ``--eta`` and the arguments above."""
    from trumans.sample.sampler import SamplerConfig

    return SamplerConfig(steps=args.steps, eta=args.eta, scene_scale=args.guidance[0], action_scale=args.guidance[1],
                         goal_guidance=args.goal_guidance, goal_iters=args.goal_iters,
                         guided_steps=args.guided_steps, guidance_space=args.guidance_space,
                         x0_guidance=args.x0_guidance, overlap=args.overlap, **postprocess_kwargs(args))
