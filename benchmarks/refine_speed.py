"""Frames per second of the HOI filter on one clip, beside Savitzky-Golay, in one run (issue 36 point 7).

    python benchmarks/refine_speed.py                       # 1 thread (trumans refine's), the longest held-out corpus clip
    python benchmarks/refine_speed.py --threads 2 --steps 1 --repeats 5 --profile

One real clip (the mocap corpus's longest test clip, 1894 frames at 30 fps) under the training
corruption is refined end to end by ``HOIFilter.refine_frames`` (one clip per call: resampling,
windows, network, every post-step) and smoothed by ``scipy.signal.savgol_filter`` (window 15,
order 2, gaps filled first), each ``--repeats`` times after one warm-up; the best and median rates
are printed (wall clock; and frames per CPU-second of the process, all its threads, which a busy
machine changes less), with the machine's load (1-minute average) when the run ended and, with
``--profile``, the filter's ten most expensive functions. ``--threads`` sets torch's and the BLAS
threads as ``trumans refine --threads`` does (``trumans.threads.set_threads``; default 1, its
default: on a shared machine more threads than free cores slow every small solve and network call
tenfold).
"""
from __future__ import annotations

import argparse
import json
import os
import sys


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--threads", type=int, default=1, help="torch and BLAS threads (default 1, trumans refine's)")
    p.add_argument("--steps", type=int, default=2, help="DDIM steps (default 2, trumans refine's)")
    p.add_argument("--repeats", type=int, default=5, help="timed runs of each method (default 5)")
    p.add_argument("--checkpoint", default=None, help="filter checkpoint (default models/refine.pt)")
    p.add_argument("--profile", action="store_true", help="print the filter's ten most expensive functions")
    args = p.parse_args(argv)
    if args.threads < 1 or args.repeats < 1 or args.steps < 1:
        p.error(f"--threads, --repeats and --steps must be >= 1, got {args.threads}, {args.repeats}, {args.steps}")
    import time

    import numpy as np

    from trumans.refine.benchmark import corrupt_family, real_body_clips, savgol_smooth
    from trumans.refine.frame import JOINTS, pack_frames
    from trumans.refine.pipeline import HOIFilter, RefineOptions
    from trumans.threads import set_threads

    set_threads(args.threads)
    clip = max(real_body_clips("test"), key=lambda c: len(c.joints))
    tracked = corrupt_family("default", [clip], 0)[0]
    frames = pack_frames(np.nan_to_num(tracked), None, np.broadcast_to(np.eye(4), (len(tracked), 4, 4)))
    frames[:, JOINTS] = tracked.reshape(len(tracked), -1)
    filt = HOIFilter.load(args.checkpoint)
    opts = RefineOptions(num_steps=args.steps)
    methods = {"filter": lambda: filt.refine_frames(frames, clip.fps, filt.categories[0], opts),
               "savgol": lambda: savgol_smooth(tracked, 15)}
    res: dict = {"clip": clip.name, "frames": len(tracked), "threads": args.threads, "steps": args.steps}
    for name, fn in methods.items():
        fn()  # warm-up
        times, cpu = [], []
        for _ in range(args.repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        res[f"{name}_frames_per_s_best"] = len(tracked) / min(times)
        res[f"{name}_frames_per_s_median"] = len(tracked) / float(np.median(times))
        res[f"{name}_frames_per_cpu_s_median"] = len(tracked) / float(np.median(cpu))
    res["savgol_over_filter"] = res["savgol_frames_per_s_median"] / res["filter_frames_per_s_median"]
    res["load_1min"] = os.getloadavg()[0]
    for k, v in res.items():
        print(f"{k:28s} {v:.1f}" if isinstance(v, float) else f"{k:28s} {v}")
    if args.profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.runcall(methods["filter"])
        pstats.Stats(prof, stream=sys.stdout).sort_stats("tottime").print_stats(10)
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
