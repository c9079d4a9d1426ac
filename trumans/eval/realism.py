"""How human a motion dataset moves: issue 9's statistics against real mocap (the held-out corpus).

Every statistic is computed per clip from its joints (z up, m) resampled to 30 fps, in the body
states ``trumans.motion_labels`` finds from the motion itself (the same rule for real and
synthetic data). A dataset's value is the median over its clips that have the state; the
reference range is the 10th-90th percentile of the per-clip values of the reference clips that
have it (min-max below 5 clips). ``inside`` = dataset value
within the range; the fraction counts statistics defined on both sides.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks

from trumans.motion_labels import MOTION_STATES, body_features, label_states, segments
from trumans.skeleton import JOINT_INDEX as J

__all__ = ["STATISTICS", "clip_statistics", "compare", "dataset_statistics", "reference_range",
           "knee_angle"]

FPS = 30.0
S = {n: i for i, n in enumerate(MOTION_STATES)}
# name -> (unit, how measured)
STATISTICS: dict[str, tuple[str, str]] = {
    "walk_jerk_p95": ("m/s^3", "95th pct of joint jerk (3rd difference x fps^3) over walking frames, all joints"),
    "knee_turning_points_per_stride": ("1", "knee-angle extrema (prominence > 3 deg) per stride while walking"),
    "cadence": ("steps/min", "steps (changes of the leading ankle along the heading) per minute walking"),
    "step_length": ("m", "pelvis ground distance per step while walking"),
    "pelvis_bob_regularity": ("1", "autocorrelation of the detrended pelvis height at one step period (walks >= 2 s)"),
    "wrist_still_share": ("1", "share of walking frames with a wrist moving < 0.1 m/s relative to the pelvis"),
    "seated_trunk_tilt": ("deg", "median trunk (pelvis->neck) tilt from vertical while sitting"),
    "seated_head_motion_5s": ("cm", "median over 5 s seated windows of the head's largest distance from its mean"),
    "seated_pelvis_motion_5s": ("cm", "same for the pelvis"),
    "lying_pelvis_motion_5s": ("cm", "same for the pelvis while lying"),
    "lying_knee_bend": ("deg", "median knee flexion (the more bent knee) while lying"),
    "sitdown_max_trunk_lean": ("deg", "largest trunk tilt during a sit-down"),
    "sitdown_head_drop": ("m", "head height at sit-down start minus at its end"),
    "sitdown_descent_10_90": ("s", "time for the pelvis to go 10 % -> 90 % of its sit-down descent"),
    "sitdown_wrist_reach": ("m", "largest forward wrist offset from the pelvis (heading frame) during a sit-down"),
    "walk_end_to_seated": ("s", "last walking frame to the first seated frame (sit-downs preceded by a walk < 6 s)"),
    "seated_foot_stagger": ("cm", "median |fore-aft offset of the two ankles| (heading frame) while sitting"),
    "standup_rise_10_90": ("s", "time for the pelvis to go 10 % -> 90 % of its stand-up rise"),
}


def _runs(states: np.ndarray, name: str, min_len: int = 1) -> list[tuple[int, int]]:
    return [(s, e) for s, e in segments(states == S[name]) if e - s >= min_len]


def _forward(heading: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(heading), np.sin(heading)], axis=-1)


def knee_angle(j: np.ndarray, side: str) -> np.ndarray:
    a = j[:, J[f"{side}_hip"]] - j[:, J[f"{side}_knee"]]
    b = j[:, J[f"{side}_ankle"]] - j[:, J[f"{side}_knee"]]
    c = (a * b).sum(-1) / np.maximum(np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1), 1e-9)
    return np.degrees(np.arccos(np.clip(c, -1, 1)))


def _window_motion(p: np.ndarray, runs: list[tuple[int, int]]) -> float | None:
    """Median over 5 s windows (1 s apart) inside runs of the largest distance from the window mean (cm)."""
    w = int(5 * FPS)
    vals = []
    for s, e in runs:
        for a in range(s, e - w + 1, int(FPS)):
            x = p[a:a + w]
            vals.append(np.linalg.norm(x - x.mean(0), axis=-1).max() * 100)
    return float(np.median(vals)) if vals else None


def _rise_time(h: np.ndarray) -> float | None:
    """Seconds between 10 % and 90 % of a monotone-ish change of h (either direction)."""
    lo, hi = h[0], h[-1]
    if abs(hi - lo) < 0.1:
        return None
    frac = (h - lo) / (hi - lo)
    i10 = int(np.argmax(frac >= 0.1))
    i90 = int(np.argmax(frac >= 0.9))
    return (i90 - i10) / FPS if i90 > i10 else None


def _sit_events(j: np.ndarray, st: np.ndarray, f: dict) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Sit-downs (a, b): from the last standing frame (pelvis >= 95 % of standing height, at most
    6 s before the seated run) to the first frame within 2 cm of the seated pelvis height; stand-ups
    (c, d): from the last such seated frame to the first standing frame (at most 6 s after)."""
    h = j[:, J["pelvis"], 2]
    standing = h >= 0.95 * f["h_stand"]
    downs, ups = [], []
    back = int(6 * FPS)
    for s, e in _runs(st, "sit", int(FPS)):
        hs = float(np.median(h[s:e]))
        settled = np.flatnonzero(h[s:e] <= hs + 0.02) + s
        if not len(settled):
            continue
        before = np.flatnonzero(standing[max(0, s - back):s]) + max(0, s - back)
        if len(before):
            a = int(before[-1])
            near = np.flatnonzero(h[a:e] <= hs + 0.02)
            downs.append((a, a + int(near[0])))
        after = np.flatnonzero(standing[e:e + back]) + e
        if len(after):
            c = int(settled[-1])
            ups.append((c, int(after[0])))
    return downs, ups


def clip_statistics(joints: np.ndarray, states: np.ndarray | None = None) -> dict[str, float | None]:
    """Every statistic of ``STATISTICS`` for one clip (T, 24, 3) at 30 fps (None where the clip
    lacks the state)."""
    j = np.asarray(joints, np.float64)
    st = label_states(j, FPS) if states is None else np.asarray(states)
    f = body_features(j, FPS)
    out: dict[str, float | None] = {k: None for k in STATISTICS}
    fwd = _forward(f["heading"])
    walks = _runs(st, "walk", int(FPS))
    if walks:
        jerk = [np.linalg.norm(np.diff(j[s:e], n=3, axis=0), axis=-1).ravel() * FPS ** 3 for s, e in walks if e - s > 3]
        out["walk_jerk_p95"] = float(np.percentile(np.concatenate(jerk), 95))
        steps, dist, dur, turning, bob, still = 0, 0.0, 0.0, 0, [], []
        for s, e in walks:
            ahead = ((j[s:e, J["left_ankle"], :2] - j[s:e, J["right_ankle"], :2]) * fwd[s:e]).sum(-1)
            big = np.flatnonzero(np.abs(ahead) > 0.02)
            cross = big[1:][np.diff(np.sign(ahead[big])) != 0]  # frames where the leading foot changes
            n = max(len(cross) - 1, 0)  # whole steps between the first and the last crossing
            if n:
                a, b = s + cross[0], s + cross[-1]
                steps += n
                dur += (b - a) / FPS
                dist += float(np.linalg.norm(np.diff(j[a:b + 1, J["pelvis"], :2], axis=0), axis=-1).sum())
            for side in ("left", "right"):
                k = knee_angle(j[s:e], side)
                turning += len(find_peaks(k, prominence=3)[0]) + len(find_peaks(-k, prominence=3)[0])
            if n >= 2 and e - s >= 2 * FPS:
                lag = int(round((cross[-1] - cross[0]) / n))
                z = j[s:e, J["pelvis"], 2]
                z = z - np.convolve(z, np.ones(lag) / lag, mode="same")
                z = z[lag:-lag] if len(z) > 3 * lag else z
                if len(z) > lag + 2 and z.std() > 1e-6:
                    bob.append(float(np.corrcoef(z[:-lag], z[lag:])[0, 1]))
            rel = j[s:e, [J["left_wrist"], J["right_wrist"]]] - j[s:e, None, J["pelvis"]]
            sp = np.linalg.norm(np.gradient(rel, axis=0), axis=-1) * FPS
            still.append((sp < 0.1).any(axis=1))
        if steps >= 2:
            out["cadence"] = steps / dur * 60
            out["step_length"] = dist / steps
            out["knee_turning_points_per_stride"] = turning / 2 / (steps / 2)
        out["pelvis_bob_regularity"] = float(np.median(bob)) if bob else None
        out["wrist_still_share"] = float(np.concatenate(still).mean())
    sits = _runs(st, "sit", int(FPS))
    if sits:
        idx = np.concatenate([np.arange(s, e) for s, e in sits])
        out["seated_trunk_tilt"] = float(np.degrees(np.median(f["tilt"][idx])))
        out["seated_head_motion_5s"] = _window_motion(j[:, J["head"]], sits)
        out["seated_pelvis_motion_5s"] = _window_motion(j[:, J["pelvis"]], sits)
        ahead = ((j[idx, J["left_ankle"], :2] - j[idx, J["right_ankle"], :2]) * fwd[idx]).sum(-1)
        out["seated_foot_stagger"] = float(np.median(np.abs(ahead)) * 100)
    lies = _runs(st, "lie", int(FPS))
    if lies:
        idx = np.concatenate([np.arange(s, e) for s, e in lies])
        out["lying_pelvis_motion_5s"] = _window_motion(j[:, J["pelvis"]], lies)
        flex = 180 - np.minimum(knee_angle(j[idx], "left"), knee_angle(j[idx], "right"))
        out["lying_knee_bend"] = float(np.median(flex))
    downs, ups = _sit_events(j, st, f)
    if downs:
        lean, drop, desc, reach, approach = [], [], [], [], []
        for a, b in downs:
            lean.append(np.degrees(f["tilt"][a:b + 1].max()))
            drop.append(j[a, J["head"], 2] - j[b, J["head"], 2])
            r = _rise_time(j[a:b + 1, J["pelvis"], 2])
            if r is not None:
                desc.append(r)
            rel = j[a:b + 1, [J["left_wrist"], J["right_wrist"]], :2] - j[a:b + 1, None, J["pelvis"], :2]
            reach.append(float(((rel * fwd[a:b + 1, None]).sum(-1)).max()))
            w0 = max(0, a - int(6 * FPS))
            prev = np.flatnonzero(st[w0:a + 1] == S["walk"])
            if len(prev):
                approach.append((b - (w0 + prev[-1])) / FPS)
        out["sitdown_max_trunk_lean"] = float(np.median(lean))
        out["sitdown_head_drop"] = float(np.median(drop))
        out["sitdown_descent_10_90"] = float(np.median(desc)) if desc else None
        out["sitdown_wrist_reach"] = float(np.median(reach))
        out["walk_end_to_seated"] = float(np.median(approach)) if approach else None
    rises = [r for r in (_rise_time(j[c:d + 1, J["pelvis"], 2]) for c, d in ups) if r is not None]
    out["standup_rise_10_90"] = float(np.median(rises)) if rises else None
    return out


def dataset_statistics(clips: list[np.ndarray]) -> tuple[dict[str, float | None], dict[str, list[float]]]:
    """Median over clips of each statistic (None if no clip has it), and the per-clip values."""
    per: dict[str, list[float]] = {k: [] for k in STATISTICS}
    for jn in clips:
        for k, v in clip_statistics(jn).items():
            if v is not None and np.isfinite(v):
                per[k].append(float(v))
    med = {k: (float(np.median(v)) if v else None) for k, v in per.items()}
    return med, per


def reference_range(values: list[float]) -> tuple[float | None, float | None]:
    """The real range of a statistic: 10th-90th percentile of the per-clip values (min-max when
    fewer than 5 clips have it)."""
    if not values:
        return None, None
    if len(values) < 5:
        return float(min(values)), float(max(values))
    return float(np.percentile(values, 10)), float(np.percentile(values, 90))


def compare(dataset: list[np.ndarray], reference: list[np.ndarray]) -> dict:
    """One JSON-able report: each statistic for the dataset and the reference range, and the
    fraction of statistics (defined on both sides) inside the reference range."""
    value, per_d = dataset_statistics(dataset)
    _, per_r = dataset_statistics(reference)
    rows, inside = {}, []
    for k, (unit, how) in STATISTICS.items():
        ref = per_r[k]
        lo, hi = reference_range(ref)
        ok = None if value[k] is None or lo is None else bool(lo <= value[k] <= hi)
        if ok is not None:
            inside.append(ok)
        rows[k] = {"unit": unit, "how": how, "dataset": value[k], "dataset_clips": len(per_d[k]),
                   "reference_min": lo, "reference_median": float(np.median(ref)) if ref else None,
                   "reference_max": hi, "reference_clips": len(ref), "inside": ok}
    return {"statistics": rows, "fraction_inside": float(np.mean(inside)) if inside else None,
            "compared": len(inside), "dataset_clips": len(dataset), "reference_clips": len(reference)}
