"""Where the HOI filter's error comes from: each corruption component alone, on held-out test clips.

    python benchmarks/refine_diagnosis.py [CHECKPOINT] [--data DIR] [--clips N] [--steps S] [--json]

For every component of ``trumans.refine.corrupt.CorruptionConfig`` (everything else off, the IMU
present and clean) it prints the input / output / Savitzky–Golay MPJPE, absolute and root-aligned
(mm), and the object errors; then the speed of the batched refiner at 1, 2 and 5 DDIM steps on the
default corruption. Figures come from ``trumans.refine.evaluate`` (same clips, same metrics).
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from trumans.refine.corrupt import CorruptionConfig  # noqa: E402

_OFF = CorruptionConfig(jitter_m=0.0, p_spike=0.0, drift_m=0.0, joint_drift_m=0.0, rot_noise_rad=0.0,
                        p_joint_occlusion=0.0, p_no_rotations=0.0, p_dropout=0.0, p_freeze=0.0, obj_jitter_m=0.0,
                        obj_drift_m=0.0, obj_rot_noise_rad=0.0, p_obj_dropout=0.0, p_flip=0.0, p_no_imu=0.0,
                        imu_bias_rad=0.0, imu_drift_rad=0.0, imu_rot_noise_rad=0.0, imu_acc_bias=0.0, imu_acc_noise=0.0)


def components() -> dict[str, CorruptionConfig]:
    d = CorruptionConfig()
    pick = lambda *names: replace(_OFF, **{n: getattr(d, n) for n in names})
    return {
        "none": _OFF,
        "jitter+spikes": pick("jitter_m", "p_spike"),
        "body_drift": pick("drift_m"),
        "joint_drift": pick("joint_drift_m"),
        "rot_noise": pick("rot_noise_rad", "p_no_rotations"),
        "occlusion+dropout+freeze": pick("p_joint_occlusion", "p_dropout", "p_freeze", "p_obj_dropout"),
        "object_noise+drift": pick("obj_jitter_m", "obj_drift_m", "obj_rot_noise_rad"),
        "object_flips": pick("p_flip"),
        "imu_noise": pick("imu_bias_rad", "imu_drift_rad", "imu_rot_noise_rad", "imu_acc_bias", "imu_acc_noise"),
        "all (default)": d,
    }


def main(argv: list[str] | None = None) -> int:
    import numpy as np

    from trumans.refine.evaluate import _clips, evaluate, tune_savgol
    from trumans.refine.pipeline import HOIFilter, RefineOptions
    from trumans.refine.corrupt import corrupt

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkpoint", nargs="?", default=None)
    p.add_argument("--data", default=None, help="dataset with val and test splits (default: the checkpoint's)")
    p.add_argument("--clips", type=int, default=20)
    p.add_argument("--steps", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    filt = HOIFilter.load(a.checkpoint)
    a.data = a.data or filt.ckpt.data.get("path")
    if not a.data or not Path(a.data).is_dir():
        raise FileNotFoundError(f"the checkpoint's dataset {a.data!r} is not on this machine; pass --data DIR")
    val, _ = _clips(a.data, "val", 192, filt.fps, filt.categories, a.clips, a.seed)
    sg = tune_savgol(list(zip(corrupt(val, filt.fps, np.random.default_rng(a.seed + 1), CorruptionConfig()), val)))
    test, cats = _clips(a.data, "test", 192, filt.fps, filt.categories, a.clips, a.seed)
    opts = RefineOptions(num_steps=a.steps, seed=a.seed)
    keys = ("mpjpe_in_mm", "mpjpe_out_mm", "mpjpe_savgol_mm", "mpjpe_in_ra_mm", "mpjpe_out_ra_mm", "mpjpe_savgol_ra_mm",
            "obj_t_err_in_cm", "obj_t_err_out_cm", "obj_rot_err_in_deg", "obj_rot_err_out_deg")
    res: dict = {"savgol_window": sg, "clips": len(test), "components": {}, "speed": {}}
    for name, cfg in components().items():
        f = evaluate(filt, test, cats, cfg, sg, a.seed, opts)
        res["components"][name] = {k: round(f[k], 2) for k in keys}
        print(f"{name:26s} " + " ".join(f"{k.replace('_mm', '').replace('mpjpe_', '')}={f[k]:.1f}" for k in keys), flush=True)
    for steps in (1, 2, 5):
        f = evaluate(filt, test, cats, CorruptionConfig(), sg, a.seed, RefineOptions(num_steps=steps, seed=a.seed),
                     per_clip_speed=True)
        res["speed"][steps] = {k: round(f[k], 2) for k in ("frames_per_s", "frames_per_s_per_clip", "mpjpe_out_mm",
                                                          "mpjpe_out_ra_mm", "obj_t_err_out_cm", "obj_rot_err_out_deg")}
        print(f"steps={steps}: {res['speed'][steps]}", flush=True)
    if a.json:
        print(json.dumps(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
