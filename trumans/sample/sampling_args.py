"""Command-line switches of the sampling-time cleanup and guidance steps, shared by
``trumans sample`` and ``trumans eval synthesis`` (one place, the same defaults as ``SamplerConfig``)."""
from __future__ import annotations

import argparse

__all__ = ["add_guidance_arguments", "add_postprocess_arguments", "postprocess_kwargs", "GOAL_GUIDANCE", "GOAL_ITERS",
           "CFG_SCALES"]

# The default goal guidance: three updates a step of size 20. One update of size 80 is ~3x faster
# (one backward pass a step instead of three) and met every target on the 6 evaluation rooms, but
# left the default room's body 9.4 cm into the chair at a sit-down (docs/sampling_log.md, sampling speed).
GOAL_GUIDANCE = 20.0
GOAL_ITERS = 3
# classifier-free guidance scales (scene, action) of the sampler; 1 = plain conditional. Action
# guidance 2 raised action accuracy 0.78 -> 0.85 and lowered fid_matched 21.8 -> 18.5 on 5 plan
# seeds, at ~1.5x the sampling time and rougher seams (jerk ratio 1.24 -> 1.46; docs/sampling_log.md)
CFG_SCALES = (1.0, 2.0)


def add_guidance_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--goal-guidance", type=float, default=GOAL_GUIDANCE,
                   help="spatial guidance step pulling the body onto each episode's goal (0 = inpainting only; "
                        f"default {GOAL_GUIDANCE:g})")
    p.add_argument("--goal-iters", type=int, default=GOAL_ITERS,
                   help=f"guidance updates per denoising step, each a backward pass (default {GOAL_ITERS})")
    p.add_argument("--guidance", type=float, nargs=2, default=CFG_SCALES, metavar=("SCENE", "ACTION"),
                   help="classifier-free guidance scales of the scene and action conditions (1 = plain conditional; "
                        f"default {CFG_SCALES[0]:g} {CFG_SCALES[1]:g})")


def add_postprocess_arguments(p: argparse.ArgumentParser) -> None:
    from trumans.sample.sampler import SamplerConfig

    d = SamplerConfig()
    g = p.add_argument_group("sampling-time cleanup (on by default)")
    g.add_argument("--no-foot-cleanup", dest="foot_cleanup", action="store_false",
                   help="keep the network's feet (no foot locks, floor or leg IK; sample/foot_cleanup.py)")
    g.add_argument("--no-support-lift", dest="support_lift", action="store_false",
                   help="keep the pelvis where the network put it after the projection onto the body's bones (the feet "
                        "then sink and the foot cleanup bends the knees; sample/support_lift.py)")
    g.add_argument("--no-seat-guidance", dest="seat_guidance", action="store_false",
                   help="do not pull a seated pelvis to its seat's height (sample/seat_guidance.py)")
    g.add_argument("--no-penetration-guidance", dest="penetration_guidance", action="store_false",
                   help="do not push the joints out of the scene (sample/penetration_guidance.py)")
    g.add_argument("--no-scene-pushout", dest="scene_pushout", action="store_false",
                   help="do not move the body out of the scene after each episode (sample/scene_pushout.py)")
    g.add_argument("--no-arm-pushout", dest="arm_pushout", action="store_false",
                   help="keep a hand that is still in the scene after the body push-out (no arm IK; "
                        "trumans/sample/cleanup/arm_pushout.py)")
    g.add_argument("--no-reach-cleanup", dest="reach_cleanup", action="store_false",
                   help="keep the network's arm at hand goals (no arm IK / lean onto handles and grasp points; "
                        "trumans/sample/cleanup/reach.py)")
    g.add_argument("--seam-blend", type=int, default=d.seam_blend, metavar="FRAMES",
                   help=f"frames over which the jump at episode seams is blended out (0 = off; default {d.seam_blend})")


def postprocess_kwargs(args: argparse.Namespace) -> dict:
    """The ``SamplerConfig`` fields set by the switches above."""
    return {"foot_cleanup": bool(args.foot_cleanup), "seam_blend": int(args.seam_blend),
            "seat_guidance": bool(args.seat_guidance), "penetration_guidance": bool(args.penetration_guidance),
            "scene_pushout": bool(args.scene_pushout), "arm_pushout": bool(args.arm_pushout), "reach_cleanup": bool(args.reach_cleanup),
            "support_lift": bool(args.support_lift)}
