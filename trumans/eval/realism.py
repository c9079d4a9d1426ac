"""How human a motion moves: the realism statistics (issues 9 and 35) against real mocap, the same
code for a dataset (the data world) and for generated motion (``trumans sample`` npz files).

Clips. Every statistic is computed per clip from its joints (z up, m) at 30 fps (``FPS``) and, for
the jerk and seam statistics, at the generator's 10 fps (``FPS_LOW``), in the body states
``trumans.motion_labels`` finds from the motion itself (the same rule for real, procedural and
generated motion). A 30 fps clip is taken to 10 fps by keeping every third frame (linear
resampling at an integer ratio, ``trumans.resample.resample_sequence``); a 10 fps clip is taken to
30 fps by a cubic spline through its frames (C2: no kinks, so no jerk spike at the 10 fps frames).
The 30 fps jerk (``walk_jerk_p95``) is measured only on clips recorded at >= 30 fps: an
interpolated frame has no jerk of its own.

Events. A clip yields zero or more *events* per statistic: one per sit-down / stand-up for those
statistics, one per clip for the walking, upright, seated and lying ones (their values pool the
clip's frames of that state), one per 30-cycle piece of a real clip for the seam statistic. An
input's value is the median over all its events.

Reference ranges (``reference_ranges``). Over every held-out real clip of the mocap corpus
(``trumans.mocap_corpus.load_corpus(split="test")``): the 10th-90th percentile (``PERCENTILES``) of
the events, with a 95 % bootstrap interval for each end from resampling *clips* with replacement
(a cluster bootstrap: events of one clip, one subject, are not independent; Efron & Tibshirani,
*An Introduction to the Bootstrap*, 1993, §8.4 and §13.3, percentile intervals; ``scipy.stats.bootstrap``,
seeded, 1,000 resamples). p10-p90, not p5-p95: the held-out corpus has 8-30 events per
transition statistic, and the 5th / 95th percentiles of so few are its extreme events (one noisy
take), which is what made the old ranges lenient. A statistic with fewer than ``MIN_EVENTS`` real
events or ``MIN_CLIPS`` real clips gets no range: it is reported as "n/a: 8 events in 5 clips" and
counted neither inside nor outside. ``inside``: the input's value within [p10, p90];
``borderline``: inside but within an end's bootstrap interval (the verdict could flip with other
held-out clips).

Postures vouched for by the description (``RealismClip.postures``). The corpus labels states from
the motion, so a squat, a stretch or a crouched "stealthy" walk can be labelled ``sit``. A reference
clip with a description counts seated, sit-down and stand-up events only if its description speaks
of sitting (``SIT_WORDS``: a chair, a stool, a bench ...), and lying events only if it speaks of
lying (``LIE_WORDS``); its walking and upright events always count (``described_postures``).
Without this the held-out squats and yoga of the 4-hour corpus widened the seated ranges (foot
stagger p90 6.7 -> 57.6 cm) and gave sit-downs of 0.2 s.

Statistics (``STATISTICS``: name -> (action, unit, definition)); the seam statistic is measured only
on generated motion (``seams`` known), furniture penetration only where the input carries its scene
(it has no real reference: corpus clips carry no furniture, so it is reported, never counted).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import find_peaks
from scipy.stats import bootstrap

from trumans.eval.synthesis_metrics import seam_jerk_peak_ratio, seam_piece_ratios
from trumans.motion_labels import MOTION_STATES, body_features, label_states, segments
from trumans.skeleton import FOOT_JOINTS, FOOT_REST_HEIGHT
from trumans.skeleton import JOINT_INDEX as J

__all__ = ["STATISTICS", "ACTIONS", "FPS", "FPS_LOW", "PERCENTILES", "MIN_EVENTS", "MIN_CLIPS", "N_BOOT",
           "RealismClip", "prepare_clip", "clip_events", "clip_statistics", "reference_ranges", "bootstrap_range",
           "score", "compare", "knee_angle", "seams_from_goals", "described_postures", "SIT_WORDS", "LIE_WORDS"]

FPS = 30.0
FPS_LOW = 10.0  # the generator's frame rate: the jerk and seam statistics are measured here
PERCENTILES = (10.0, 90.0)  # the real range (module doc: why not 5-95)
MIN_EVENTS, MIN_CLIPS = 10, 3  # fewer real events / clips: no range ("n/a")
N_BOOT = 1000  # bootstrap resamples of the reference clips
CONTACT_HEIGHT = 0.05  # m above a foot joint's resting height (``_feet``): it touches the floor (as foot_skate_near_floor_cm)
SKATE_SPEED = 0.10  # m/s: a touching foot joint moving faster slides
SEAM_PIECE_CYCLES = 30  # real clips are folded in pieces of this many cycles (synthesis_metrics.seam_piece_ratios)
S = {n: i for i, n in enumerate(MOTION_STATES)}
UPRIGHT = [S["stand"], S["walk"], S["turn"]]
ACTIONS = ("walk", "upright", "seated", "lie", "sit-down", "stand-up", "seams", "scene")
# name -> (action, unit, how measured)
STATISTICS: dict[str, tuple[str, str, str]] = {
    "walk_jerk_p95": ("walk", "m/s^3", "95th pct of joint jerk (3rd difference x 30^3) over walking frames at 30 fps, all "
                      "joints; clips recorded at >= 30 fps only"),
    "walk_jerk_p95_10fps": ("walk", "m/s^3", "95th pct of joint jerk (3rd difference x 10^3) over walking frames at 10 fps"),
    "knee_turning_points_per_stride": ("walk", "1", "knee-angle extrema (prominence > 3 deg) per stride while walking"),
    "cadence": ("walk", "steps/min", "steps (changes of the leading ankle along the heading) per minute walking"),
    "step_length": ("walk", "m", "pelvis ground distance per step while walking"),
    "pelvis_bob_regularity": ("walk", "1", "autocorrelation of the detrended pelvis height at a lag of one step "
                              "(walks >= 2 s)"),
    "wrist_still_share": ("walk", "1", "share of walking frames with a wrist moving < 0.1 m/s relative to the pelvis"),
    "walk_foot_skate_share": ("walk", "1", "share of foot-contact frames (a foot joint within 5 cm of its resting "
                              "height, its 5th-pct height when upright) while walking whose foot joint slides faster than 10 cm/s horizontally"),
    "stand_foot_skate_share": ("upright", "1", "the same while standing (stand / turn frames)"),
    "both_feet_off_share": ("upright", "1", "share of stand / walk / turn frames with no foot joint within 5 cm of its "
                            "resting height (as above)"),
    "seated_trunk_tilt": ("seated", "deg", "median trunk (pelvis->neck) tilt from vertical while sitting"),
    "seated_head_motion_5s": ("seated", "cm", "median over 5 s seated windows of the head's largest distance from its mean"),
    "seated_pelvis_motion_5s": ("seated", "cm", "same for the pelvis"),
    "seated_foot_stagger": ("seated", "cm", "median |fore-aft offset of the two ankles| (heading frame) while sitting"),
    "seated_jerk_median_10fps": ("seated", "m/s^3", "median joint jerk (3rd difference x 10^3) over seated frames at 10 fps"),
    "lying_pelvis_motion_5s": ("lie", "cm", "median over 5 s lying windows of the pelvis' largest distance from its mean"),
    "lying_head_motion_5s": ("lie", "cm", "same for the head"),
    "lying_knee_bend": ("lie", "deg", "median knee flexion (the more bent knee) while lying"),
    "sitdown_max_trunk_lean": ("sit-down", "deg", "largest trunk tilt during a sit-down"),
    "sitdown_head_drop": ("sit-down", "m", "head height at sit-down start minus at its end"),
    "sitdown_descent_10_90": ("sit-down", "s", "time for the pelvis to go 10 % -> 90 % of its sit-down descent"),
    "sitdown_backward_shove": ("sit-down", "m/s", "largest backward pelvis ground speed (against the hips' facing) "
                               "during a sit-down, 0 if it never moves back"),
    "sitdown_wrist_reach": ("sit-down", "m", "largest forward wrist offset from the pelvis (heading frame) during a sit-down"),
    "sitdown_wrist_height_asymmetry": ("sit-down", "m", "mean |left - right wrist height| during a sit-down"),
    "walk_end_to_seated": ("sit-down", "s", "last walking frame to the first seated frame (sit-downs preceded by a walk "
                           "< 6 s)"),
    "standup_rise_10_90": ("stand-up", "s", "time for the pelvis to go 10 % -> 90 % of its stand-up rise"),
    "standup_pause_to_walk": ("stand-up", "s", "end of the rise (pelvis back at 95 % of standing height) to the first "
                              "walking frame (stand-ups followed by a walk < 6 s; negative: walking before upright)"),
    "seam_jerk_peak_ratio": ("seams", "1", "10 fps joint jerk folded on the episode cycle: loudest phase / median phase "
                             "(synthesis_metrics.seam_jerk_peak_ratio); real: the same fold on 30-cycle pieces"),
    "furniture_penetration_max_cm": ("scene", "cm", "deepest body penetration into the scene's furniture (floor and "
                                     "carried objects excluded; synthesis_metrics.penetration_cm)"),
}
NO_REFERENCE = {"furniture_penetration_max_cm": "no real reference: corpus clips carry no furniture"}
SIT_WORDS = re.compile(r"\bsit|\bsat\b|seat|chair|stool|bench|couch|sofa", re.I)
LIE_WORDS = re.compile(r"\blay|\blie\b|\blies\b|lying|laying|\bbed\b|\bfloor\b|ground", re.I)
SIT_FAMILY = ("seated", "sit-down", "stand-up")  # the actions whose events need a sitting description


def described_postures(description: str) -> tuple[str, ...]:
    """("sit", "lie") or a part of it: the postures a clip's description speaks of (module doc)."""
    return tuple(p for p, rx in (("sit", SIT_WORDS), ("lie", LIE_WORDS)) if rx.search(description or ""))


@dataclass
class RealismClip:
    """One clip to measure. joints: (T, 24, 3) m z-up at ``fps``; states: (T30,) indices into
    ``MOTION_STATES`` at 30 fps (None: labelled from the motion); seams: (cycle, first seam frame) at
    ``fps`` of generated motion (None: not generated); scene: a ``trumans.scenes.Scene`` the motion
    happens in (None: none carried); name: for messages; postures: the postures whose events count
    (``described_postures`` of a reference clip's description; None: every posture)."""

    joints: np.ndarray
    fps: float = FPS
    states: np.ndarray | None = None
    seams: tuple[int, int] | None = None
    scene: object | None = None
    name: str = ""
    postures: tuple[str, ...] | None = None


def seams_from_goals(goals: np.ndarray, goal_joints: np.ndarray) -> tuple[int, int] | None:
    """A sampled npz's ``extra/goals`` (K, 4) rows (frame, x, y, z) and ``extra/goal_joints`` (K,) ->
    (cycle, first seam) in frames: each pelvis goal is due on its episode's last frame
    (``trumans.sample.rollout``), so the seams (an episode's first new frame) are those frames + 1 and
    the cycle is the greatest common divisor of their spacings. None with fewer than 2 pelvis goals."""
    f = np.unique(np.asarray(goals, np.float64)[np.asarray(goal_joints).astype(str) == "pelvis", 0].astype(np.int64))
    if len(f) < 2:
        return None
    cycle = int(np.gcd.reduce(np.diff(f)))
    return (cycle, int((f[0] + 1) % cycle)) if cycle >= 2 else None


def prepare_clip(joints: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """joints (T, 24, 3) m at ``fps`` -> (at 30 fps, at 10 fps), float64 (module doc: how)."""
    from trumans.resample import resample_times

    j = np.asarray(joints, np.float64)
    if j.ndim != 3 or j.shape[1:] != (24, 3) or len(j) < 2:
        raise ValueError(f"joints must be (T >= 2, 24, 3), got {j.shape}")
    if not np.isfinite(j).all():
        raise ValueError("joints contain NaN or inf; realism is measured on complete motion only")

    def to(rate: float) -> np.ndarray:
        if abs(fps - rate) < 1e-9:
            return j
        t = resample_times(len(j), fps, rate)
        if fps > rate:  # downsampling: linear (an integer ratio keeps every k-th frame), as resample_sequence
            i0 = np.floor(t).astype(int)
            i1 = np.minimum(i0 + 1, len(j) - 1)
            w = (t - i0)[:, None, None]
            return (1 - w) * j[i0] + w * j[i1]
        return CubicSpline(np.arange(len(j)), j, axis=0)(t)

    return to(FPS), to(FPS_LOW)


def _runs(states: np.ndarray, name: str, min_len: int = 1) -> list[tuple[int, int]]:
    return [(s, e) for s, e in segments(states == S[name]) if e - s >= min_len]


def _forward(heading: np.ndarray) -> np.ndarray:
    return np.stack([np.cos(heading), np.sin(heading)], axis=-1)


def knee_angle(j: np.ndarray, side: str) -> np.ndarray:
    """joints (T, 24, 3) -> (T,) angle at the ``side`` ('left' / 'right') knee between thigh and shin, deg
    (180 = straight)."""
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


def _jerk(j: np.ndarray, runs: list[tuple[int, int]], fps: float) -> np.ndarray:
    """Joint jerk magnitudes (m/s^3) of every 4-frame window inside the runs, all joints pooled."""
    parts = [np.linalg.norm(np.diff(j[s:e], n=3, axis=0), axis=-1).ravel() * fps ** 3 for s, e in runs if e - s > 3]
    return np.concatenate(parts) if parts else np.zeros(0)


def _gait(j: np.ndarray, walks: list[tuple[int, int]], fwd: np.ndarray, out: dict[str, list[float]]) -> None:
    """Cadence, step length, knee turning points, pelvis bob and wrist stillness of the walking runs."""
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
        out["cadence"].append(steps / dur * 60)
        out["step_length"].append(dist / steps)
        out["knee_turning_points_per_stride"].append(turning / 2 / (steps / 2))
    if bob:
        out["pelvis_bob_regularity"].append(float(np.median(bob)))
    out["wrist_still_share"].append(float(np.concatenate(still).mean()))


def _feet(j: np.ndarray, st: np.ndarray, out: dict[str, list[float]]) -> None:
    """walk_foot_skate_share, stand_foot_skate_share and both_feet_off_share (clips with >= 1 s of the state).
    A foot joint's resting height is its 5th-percentile height over the clip's upright frames (the
    skeletons differ: a CMU ankle rests ~3 cm higher than ours), else ``FOOT_REST_HEIGHT``."""
    feet = j[:, list(FOOT_JOINTS)]  # (T, 4, 3)
    up = np.isin(st, UPRIGHT)
    rest = np.percentile(feet[up, :, 2], 5, axis=0) if up.sum() >= FPS else FOOT_REST_HEIGHT
    touch = (feet[..., 2] - rest) < CONTACT_HEIGHT  # (T, 4)
    speed = np.linalg.norm(np.gradient(feet[..., :2], axis=0), axis=-1) * FPS  # (T, 4) m/s
    for name, states in (("walk_foot_skate_share", [S["walk"]]), ("stand_foot_skate_share", [S["stand"], S["turn"]])):
        sel = np.isin(st, states)
        contact = touch & sel[:, None]
        if sel.sum() >= FPS and contact.any():
            out[name].append(float((contact & (speed > SKATE_SPEED)).sum() / contact.sum()))
    if up.sum() >= FPS:
        out["both_feet_off_share"].append(float((~touch[up].any(axis=1)).mean()))


def _sit_downs(j: np.ndarray, st: np.ndarray, f: dict, fwd: np.ndarray, downs: list[tuple[int, int]],
               out: dict[str, list[float]]) -> None:
    """The sit-down statistics, one event per sit-down (a, b)."""
    vel = np.gradient(j[:, J["pelvis"], :2], axis=0) * FPS  # (T, 2) m/s
    for a, b in downs:
        out["sitdown_max_trunk_lean"].append(float(np.degrees(f["tilt"][a:b + 1].max())))
        out["sitdown_head_drop"].append(float(j[a, J["head"], 2] - j[b, J["head"], 2]))
        r = _rise_time(j[a:b + 1, J["pelvis"], 2])
        if r is not None:
            out["sitdown_descent_10_90"].append(r)
        back = -(vel[a:b + 1] * fwd[a:b + 1]).sum(-1)
        out["sitdown_backward_shove"].append(float(max(0.0, back.max())))
        rel = j[a:b + 1, [J["left_wrist"], J["right_wrist"]], :2] - j[a:b + 1, None, J["pelvis"], :2]
        out["sitdown_wrist_reach"].append(float(((rel * fwd[a:b + 1, None]).sum(-1)).max()))
        out["sitdown_wrist_height_asymmetry"].append(
            float(np.abs(j[a:b + 1, J["left_wrist"], 2] - j[a:b + 1, J["right_wrist"], 2]).mean()))
        w0 = max(0, a - int(6 * FPS))
        prev = np.flatnonzero(st[w0:a + 1] == S["walk"])
        if len(prev):
            out["walk_end_to_seated"].append((b - (w0 + prev[-1])) / FPS)


def _stand_ups(j: np.ndarray, st: np.ndarray, ups: list[tuple[int, int]], out: dict[str, list[float]]) -> None:
    """The stand-up statistics, one event per stand-up (c, d)."""
    for c, d in ups:
        r = _rise_time(j[c:d + 1, J["pelvis"], 2])
        if r is not None:
            out["standup_rise_10_90"].append(r)
        walk = np.flatnonzero(st[c:d + int(6 * FPS)] == S["walk"])
        if len(walk):
            out["standup_pause_to_walk"].append((c + int(walk[0]) - d) / FPS)


def _furniture_penetration_cm(joints: np.ndarray, scene) -> float:
    """Deepest body penetration (cm) into the scene's static meshes and non-dynamic objects."""
    from trumans.contacts.rule import ContactScene
    from trumans.eval.synthesis_metrics import penetration_cm
    from trumans.scenes.scene import Scene

    fixed = Scene(name=scene.name, static=dict(scene.static),
                  objects={n: o for n, o in scene.objects.items() if not o.dynamic})
    return penetration_cm(np.asarray(joints, np.float64), ContactScene(fixed, floor=False))[1]


def clip_events(clip: RealismClip | np.ndarray, states: np.ndarray | None = None) -> dict[str, list[float]]:
    """Every statistic's events (module doc) of one clip: name -> list of values (units of
    ``STATISTICS``), empty where the clip lacks the state / event. ``clip``: a ``RealismClip`` or joints
    (T, 24, 3) at 30 fps (with ``states`` at 30 fps or None)."""
    if not isinstance(clip, RealismClip):
        clip = RealismClip(np.asarray(clip), FPS, states)
    j, j10 = prepare_clip(clip.joints, clip.fps)
    out: dict[str, list[float]] = {k: [] for k in STATISTICS}
    st = label_states(j, FPS) if clip.states is None else np.asarray(clip.states)
    if len(st) != len(j):
        raise ValueError(f"{clip.name or 'clip'}: {len(st)} states for {len(j)} frames at 30 fps")
    st10 = st[np.clip(np.rint(np.arange(len(j10)) * FPS / FPS_LOW).astype(int), 0, len(st) - 1)]
    f = body_features(j, FPS)
    fwd = _forward(f["heading"])
    walks = _runs(st, "walk", int(FPS))
    if walks:
        if clip.fps >= FPS - 1e-9:
            jerk = _jerk(j, walks, FPS)
            if jerk.size:
                out["walk_jerk_p95"].append(float(np.percentile(jerk, 95)))
        _gait(j, walks, fwd, out)
    jerk10 = _jerk(j10, _runs(st10, "walk", int(FPS_LOW)), FPS_LOW)
    if jerk10.size:
        out["walk_jerk_p95_10fps"].append(float(np.percentile(jerk10, 95)))
    _feet(j, st, out)
    sits = _runs(st, "sit", int(FPS))
    if sits:
        idx = np.concatenate([np.arange(s, e) for s, e in sits])
        out["seated_trunk_tilt"].append(float(np.degrees(np.median(f["tilt"][idx]))))
        for name, joint in (("seated_head_motion_5s", "head"), ("seated_pelvis_motion_5s", "pelvis")):
            m = _window_motion(j[:, J[joint]], sits)
            if m is not None:
                out[name].append(m)
        ahead = ((j[idx, J["left_ankle"], :2] - j[idx, J["right_ankle"], :2]) * fwd[idx]).sum(-1)
        out["seated_foot_stagger"].append(float(np.median(np.abs(ahead)) * 100))
    jerk10 = _jerk(j10, _runs(st10, "sit", int(FPS_LOW)), FPS_LOW)
    if jerk10.size:
        out["seated_jerk_median_10fps"].append(float(np.median(jerk10)))
    lies = _runs(st, "lie", int(FPS))
    if lies:
        idx = np.concatenate([np.arange(s, e) for s, e in lies])
        for name, joint in (("lying_pelvis_motion_5s", "pelvis"), ("lying_head_motion_5s", "head")):
            m = _window_motion(j[:, J[joint]], lies)
            if m is not None:
                out[name].append(m)
        flex = 180 - np.minimum(knee_angle(j[idx], "left"), knee_angle(j[idx], "right"))
        out["lying_knee_bend"].append(float(np.median(flex)))
    downs, ups = _sit_events(j, st, f)
    _sit_downs(j, st, f, fwd, downs, out)
    _stand_ups(j, st, ups, out)
    if clip.seams is not None:
        cycle, first = clip.seams
        r, _ = seam_jerk_peak_ratio(np.asarray(clip.joints, np.float64), cycle, first)
        if np.isfinite(r):
            out["seam_jerk_peak_ratio"].append(r)
    if clip.scene is not None:
        out["furniture_penetration_max_cm"].append(_furniture_penetration_cm(clip.joints, clip.scene))
    if clip.postures is not None:  # only the postures its description vouches for (module doc)
        for k, (action, _, _) in STATISTICS.items():
            if (action in SIT_FAMILY and "sit" not in clip.postures) or (action == "lie" and "lie" not in clip.postures):
                out[k] = []
    return out


def clip_statistics(joints: np.ndarray, states: np.ndarray | None = None) -> dict[str, float | None]:
    """Every statistic of ``STATISTICS`` for one clip (T, 24, 3) at 30 fps: the median of its events
    (``clip_events``), None where the clip has none."""
    return {k: (float(np.median(v)) if v else None) for k, v in clip_events(joints, states).items()}


def bootstrap_range(per_clip: list[np.ndarray], q: tuple[float, float] = PERCENTILES, n_boot: int = N_BOOT,
                    seed: int = 0) -> tuple[float, float, tuple[float, float], tuple[float, float]]:
    """Events grouped by clip (a list of (n_i,) arrays, n_i >= 1) -> (lo, hi, lo's 95 % interval,
    hi's 95 % interval): the ``q`` percentiles of all events, and percentile-bootstrap intervals from
    ``n_boot`` resamples of the clips with replacement (module doc), seeded by ``seed``."""
    groups = [np.asarray(v, np.float64).ravel() for v in per_clip]
    groups = [g for g in groups if g.size]
    if not groups:
        raise ValueError("bootstrap_range needs at least one clip with an event")
    lo, hi = np.percentile(np.concatenate(groups), q)
    if len(groups) < 2:
        return float(lo), float(hi), (float(lo), float(lo)), (float(hi), float(hi))

    def stat(idx: np.ndarray) -> np.ndarray:
        return np.percentile(np.concatenate([groups[int(i)] for i in idx]), q)

    ci = bootstrap((np.arange(len(groups)),), stat, vectorized=False, n_resamples=int(n_boot), method="percentile",
                   confidence_level=0.95, rng=np.random.default_rng(seed)).confidence_interval
    return (float(lo), float(hi), (float(ci.low[0]), float(ci.high[0])), (float(ci.low[1]), float(ci.high[1])))


def _events(clips: list[RealismClip]) -> dict[str, list[np.ndarray]]:
    """name -> per-clip event arrays (clips with no event of the statistic left out)."""
    per: dict[str, list[np.ndarray]] = {k: [] for k in STATISTICS}
    for c in clips:
        for k, v in clip_events(c).items():
            v = [x for x in v if np.isfinite(x)]
            if v:
                per[k].append(np.asarray(v, np.float64))
    return per


def reference_ranges(reference: list[RealismClip], *, seam_cycle: int | None = None, n_boot: int = N_BOOT,
                     seed: int = 0, min_events: int = MIN_EVENTS, min_clips: int = MIN_CLIPS) -> dict[str, dict]:
    """name -> the real range of every statistic (module doc): events, clips, median, lo / hi (p10 /
    p90) and their bootstrap intervals, or lo = hi = None and ``note`` "n/a: ..." when the real
    events are too few. ``seam_cycle``: the generated motion's episode cycle (frames at 10 fps); the
    reference clips are folded on it in pieces of ``SEAM_PIECE_CYCLES`` cycles."""
    per = _events(reference)
    if seam_cycle is not None:
        per["seam_jerk_peak_ratio"] = [np.asarray(v) for v in (
            seam_piece_ratios(prepare_clip(c.joints, c.fps)[1], int(seam_cycle), SEAM_PIECE_CYCLES) for c in reference) if v]
    out = {}
    for i, k in enumerate(STATISTICS):
        groups = per[k]
        n, c = int(sum(len(g) for g in groups)), len(groups)
        row = {"events": n, "clips": c, "median": float(np.median(np.concatenate(groups))) if n else None,
               "lo": None, "hi": None, "lo_ci": None, "hi_ci": None, "note": None}
        if k in NO_REFERENCE:
            row["note"] = NO_REFERENCE[k]
        elif k == "seam_jerk_peak_ratio" and seam_cycle is None:
            row["note"] = "n/a: no episode seams to fold on"
        elif n < min_events or c < min_clips:
            row["note"] = f"n/a: {n} events in {c} clips (a range needs >= {min_events} events in >= {min_clips} clips)"
        else:
            lo, hi, lo_ci, hi_ci = bootstrap_range(groups, PERCENTILES, n_boot, seed + i)
            row.update(lo=lo, hi=hi, lo_ci=list(lo_ci), hi_ci=list(hi_ci))
        out[k] = row
    return out


def score(inputs: list[RealismClip], reference: list[RealismClip], *, n_boot: int = N_BOOT, seed: int = 0,
          min_events: int = MIN_EVENTS, min_clips: int = MIN_CLIPS) -> dict:
    """The realism report of ``inputs`` (a dataset's clips or generated sequences) against
    ``reference`` (real clips): per statistic the input's value (median of its events), the real
    range (``reference_ranges``), ``inside`` (True / False; None where either side is missing) and
    ``borderline``; ``inside_count`` of ``compared`` statistics. JSON-able."""
    if not inputs:
        raise ValueError("nothing to measure: no input clips")
    if not reference:
        raise ValueError("no reference clips to compare with")
    cycles = {c.seams[0] for c in inputs if c.seams is not None}
    if len(cycles) > 1:
        raise ValueError(f"the generated inputs have different episode cycles {sorted(cycles)}; score them separately")
    per = _events(inputs)
    ref = reference_ranges(reference, seam_cycle=next(iter(cycles)) if cycles else None, n_boot=n_boot, seed=seed,
                           min_events=min_events, min_clips=min_clips)
    rows, inside = {}, []
    for k, (action, unit, how) in STATISTICS.items():
        groups = per[k]
        value = float(np.median(np.concatenate(groups))) if groups else None
        r = ref[k]
        ok = border = None
        if value is not None and r["lo"] is not None:
            ok = bool(r["lo"] <= value <= r["hi"])
            border = bool(ok and (value <= r["lo_ci"][1] or value >= r["hi_ci"][0]))
            inside.append(ok)
        note = r["note"]
        if value is None and k == "walk_jerk_p95" and any(c.fps < FPS - 1e-9 for c in inputs):
            note = "not measured: input below 30 fps (see walk_jerk_p95_10fps)"
        elif value is None:
            note = "not measured: " + {"seams": "no episode seams (only generated motion has them)",
                                       "scene": "the input carries no scene"}.get(action, f"no {action} in the input")
        rows[k] = {"action": action, "unit": unit, "how": how, "value": value,
                   "events": int(sum(len(g) for g in groups)), "clips": len(groups), "reference": r,
                   "inside": ok, "borderline": border, "note": note}
    return {"statistics": rows, "inside_count": int(sum(inside)), "compared": len(inside),
            "fraction_inside": float(np.mean(inside)) if inside else None,
            "clips": len(inputs), "reference_clips": len(reference),
            "percentiles": list(PERCENTILES), "bootstrap_resamples": int(n_boot), "seed": int(seed),
            "min_events": int(min_events), "min_clips": int(min_clips)}


def compare(dataset: list[np.ndarray], reference: list[np.ndarray], **kw) -> dict:
    """``score`` of joint arrays (T, 24, 3) at 30 fps (states labelled from the motion)."""
    return score([RealismClip(np.asarray(j), FPS) for j in dataset],
                 [RealismClip(np.asarray(j), FPS) for j in reference], **kw)
