"""Body states found from the motion itself: standing, walking, turning, sitting, lying, and the
transitions between them, named with the synthetic vocabulary (``trumans.synth.vocab``).

Per frame (z up, metres): hip height (the hip joints' midpoint, the same in every skeleton convention)
against the standing hip height (where the body stands straight),
hip ground speed, heading rate, trunk tilt (hips -> neck against vertical) and thigh angle.
States are smoothed with a 0.5 s majority window. Each posture change around a sitting / lying run is
then labelled whole, as the procedural takes label it: ``sit_down`` / ``lie_down`` from the last upright
frame (hips at >= 97 % of the standing height) until the hips settle at the held height, ``stand_up``
/ ``get_up`` from the last settled frame until the hips are upright again (issue 35: the sit state
began at 88 % of the standing height, so ``sit_down`` held 8 % of the real takes' hip drop).
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from .skeleton import JOINT_INDEX

__all__ = ["MOTION_STATES", "MOTION_TYPES", "body_features", "label_states", "motion_types", "segments"]

MOTION_STATES: tuple[str, ...] = ("stand", "walk", "turn", "sit_down", "sit", "stand_up", "lie_down", "lie", "get_up")
# The coarser motion types results are reported by (issue 36): groups of states, and picking up (from labels).
MOTION_TYPES: tuple[str, ...] = ("walk", "sit", "lie", "get_up", "pick_up")
_STATES_OF = {"walk": ("walk", "turn"), "sit": ("sit_down", "sit", "stand_up"), "lie": ("lie_down", "lie"),
              "get_up": ("get_up",)}
J = JOINT_INDEX
WALK_SPEED = 0.35  # m/s, pelvis ground speed (0.5 s mean) above which the body walks
TURN_RATE = np.deg2rad(45.0)  # rad/s heading rate above which a body that does not walk turns
UPRIGHT = 0.97  # hips at this share of the standing hip height or above: the body is upright
SETTLED = 0.05  # hips within this share of the drop (or 2 cm) of their held height: settled


def body_features(joints: np.ndarray, fps: float) -> dict[str, np.ndarray]:
    """Per-frame features of joints (T, 24, 3): hip-midpoint height ``h`` (m), standing hip height
    ``h_stand`` (scalar, m), ground ``speed`` (m/s), ``heading`` and ``yaw_rate`` (rad, rad/s), trunk
    ``tilt`` (rad from vertical), mean ``thigh`` angle from vertical (rad)."""
    joints = np.asarray(joints, np.float64)
    win = max(1, int(round(0.5 * fps)))
    pel = 0.5 * (joints[:, J["left_hip"]] + joints[:, J["right_hip"]])  # hip joints: the same in every skeleton convention
    thigh_len = np.median(np.linalg.norm(joints[:, J["left_knee"]] - joints[:, J["left_hip"]], axis=-1))
    shin_len = np.median(np.linalg.norm(joints[:, J["left_ankle"]] - joints[:, J["left_knee"]], axis=-1))
    trunk = joints[:, J["neck"]] - pel
    tilt = np.arccos(np.clip(trunk[:, 2] / np.maximum(np.linalg.norm(trunk, axis=-1), 1e-9), -1, 1))
    th = []
    for s in ("left", "right"):
        d = joints[:, J[f"{s}_knee"]] - joints[:, J[f"{s}_hip"]]
        th.append(np.arccos(np.clip(-d[:, 2] / np.maximum(np.linalg.norm(d, axis=-1), 1e-9), -1, 1)))
    thigh = np.mean(th, axis=0)
    upright = (thigh < np.deg2rad(15)) & (tilt < np.deg2rad(20))
    # standing pelvis height: measured where the body stands straight, else from the leg bones
    h_stand = float(np.median(pel[upright, 2])) if upright.sum() >= fps else thigh_len + shin_len + 0.05
    vel = np.gradient(pel[:, :2], axis=0) * fps
    speed = uniform_filter1d(np.linalg.norm(vel, axis=-1), win, mode="nearest")
    across = joints[:, J["left_hip"], :2] - joints[:, J["right_hip"], :2]
    heading = np.unwrap(np.arctan2(-across[:, 0], across[:, 1]))  # forward = left-axis turned -90 deg
    yaw_rate = uniform_filter1d(np.gradient(heading) * fps, win, mode="nearest")
    return {"h": pel[:, 2], "h_stand": np.asarray(h_stand), "speed": speed, "heading": heading,
            "yaw_rate": yaw_rate, "tilt": tilt, "thigh": thigh}


def label_states(joints: np.ndarray, fps: float) -> np.ndarray:
    """Per-frame state index into ``MOTION_STATES`` (T,) int."""
    f = body_features(joints, fps)
    T = len(f["h"])
    rel = f["h"] / f["h_stand"]
    lie = (f["tilt"] > np.deg2rad(60)) & (rel < 0.75)  # on the floor or a bed
    sit = ~lie & (rel < 0.88) & (f["thigh"] > np.deg2rad(40)) & (f["speed"] < WALK_SPEED)  # chairs to high stools (hips at 0.87 of standing)
    walk = ~lie & ~sit & (f["speed"] > WALK_SPEED)
    turn = ~lie & ~sit & ~walk & (np.abs(f["yaw_rate"]) > TURN_RATE)
    base = np.zeros(T, np.int64)  # stand
    base[walk] = MOTION_STATES.index("walk")
    base[turn] = MOTION_STATES.index("turn")
    base[sit] = MOTION_STATES.index("sit")
    base[lie] = MOTION_STATES.index("lie")
    base = _majority(base, max(1, int(round(0.5 * fps))))
    return _transitions(base, f["h"], float(f["h_stand"]), fps)


def _transitions(base: np.ndarray, h: np.ndarray, h_stand: float, fps: float) -> np.ndarray:
    """Relabel the posture changes around each held ``sit`` / ``lie`` run of ``base`` (T,) as the
    transition states, each covering the whole change of hip height ``h`` (T,) m: ``sit_down`` /
    ``lie_down`` from the last upright frame (hips at >= ``UPRIGHT`` of ``h_stand``) until the hips
    settle at the held height (the run's median, within ``SETTLED`` of the drop or 2 cm);
    ``stand_up`` / ``get_up`` from the last settled frame until the hips are upright again. A
    transition reaches at most 3 s outside its held run and never into another held run."""
    base = base.copy()
    T = len(base)
    upright = h >= UPRIGHT * h_stand
    longest = int(round(3 * fps))
    held = np.isin(base, [MOTION_STATES.index("sit"), MOTION_STATES.index("lie")])
    for state, before, after in (("sit", "sit_down", "stand_up"), ("lie", "lie_down", "get_up")):
        for s, e in segments(base == MOTION_STATES.index(state)):
            h_held = float(np.median(h[s:e]))
            tol = max(0.01, SETTLED * (h_stand - h_held))
            off = np.abs(h[s:e] - h_held)
            settled = np.flatnonzero(off <= max(tol, off.min())) + s
            i = s
            while i > max(0, s - longest) and not upright[i - 1] and not held[i - 1]:
                i -= 1
            base[i:settled[0]] = MOTION_STATES.index(before)
            i = e
            while i < min(T, e + longest) and not upright[i] and not held[i]:
                i += 1
            base[settled[-1] + 1:i] = MOTION_STATES.index(after)
    return base


def _majority(labels: np.ndarray, win: int) -> np.ndarray:
    """Most common label in a centred window of ``win`` frames."""
    n = len(MOTION_STATES)
    onehot = np.eye(n)[labels]
    votes = uniform_filter1d(onehot, win, axis=0, mode="nearest")
    return np.argmax(votes, axis=1)


def segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True in a (T,) bool mask."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(d[::2].tolist(), d[1::2].tolist()))


def motion_types(joints: np.ndarray, fps: float, pick_up: np.ndarray | None = None) -> np.ndarray:
    """(T, len(MOTION_TYPES)) bool per frame: walk / sit / lie / get_up from the body's own states
    (``label_states``, the same rule for real and synthetic motion), pick_up from ``pick_up`` (T,) bool
    (a clip's description or action labels; None: never)."""
    s = np.asarray(label_states(joints, fps))
    out = np.zeros((len(s), len(MOTION_TYPES)), bool)
    for i, t in enumerate(MOTION_TYPES[:-1]):
        out[:, i] = np.isin(s, [MOTION_STATES.index(n) for n in _STATES_OF[t]])
    if pick_up is not None:
        out[:, -1] = np.asarray(pick_up, bool)
    return out
