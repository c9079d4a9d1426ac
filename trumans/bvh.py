"""BVH motion files: a generic reader and a writer for our 24-joint skeleton (the importer of any
skeleton is ``trumans.importers.bvh.import_bvh``).

Conventions owned here:
- Rotation channels: a joint's rotation is the product of its rotation channels *in the order they
  are listed* (``Zrotation Xrotation Yrotation`` -> ``R = Rz @ Rx @ Ry``, degrees), acting on column
  vectors: ``x_parent = R @ x_local + t``. Any order the file lists is read.
- Position channels: where a joint has them (the root; some files give other joints 6 channels)
  the channel values *replace* the joint's OFFSET as its translation (as Blender does); a missing
  axis keeps the OFFSET's value. Joints without position channels are translated by their OFFSET.
- ``write_bvh`` writes our skeleton (``trumans.skeleton.JOINT_NAMES``) in metres, **y-up**, in the
  project's one y-up frame (``trumans.rotations.Y_UP_TO_Z_UP``, also the GLB's and mesh import's):
  ``(X, Y, Z)_bvh = (x, z, -y)_ours``, which Blender's BVH importer (forward -Z, up Y) turns back into
  our world exactly, so a BVH and a GLB of one sequence overlay in one scene; the root has
  6 channels ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``, others 3 (ZXY);
  leaf joints get an End Site. ``trumans.importers.bvh.import_bvh(..., up="y")`` converts back to our z-up.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .input_files import check_input_file
from .limits import check_fps, check_frames
from .rotations import Y_UP_TO_Z_UP
from .sequence import atomic_write
from .skeleton import JOINT_NAMES, NUM_JOINTS, children

__all__ = ["BvhData", "read_bvh", "write_bvh", "Y_UP_FROM_Z_UP", "CORPUS_Y_UP_FROM_Z_UP", "CORPUS_FROM_PROJECT_TURN"]

# (X, Y, Z)_bvh = C @ (x, y, z)_ours = (x, z, -y): the project's y-up frame (module doc)
Y_UP_FROM_Z_UP: np.ndarray = Y_UP_TO_Z_UP.T
# the CMU corpus build's turn of its y-up takes, (X, Y, Z)_file = (y, z, x)_ours (a cyclic permutation): which
# horizontal file axis becomes our x is arbitrary for a take; kept so the corpus rebuild stays byte-identical
CORPUS_Y_UP_FROM_Z_UP: np.ndarray = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
# row-vector turn from the project's frame of a y-up take to the corpus' (+90 deg about z): p_corpus = p @ this
CORPUS_FROM_PROJECT_TURN: np.ndarray = Y_UP_TO_Z_UP @ CORPUS_Y_UP_FROM_Z_UP
_AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass
class BvhData:
    """A parsed BVH file (file units, file axes).

    names: (J,) joint names; parents: (J,) int, -1 for the root(s); offsets: (J, 3);
    channels: per joint, its channel names (e.g. ``["Zrotation", "Xrotation", "Yrotation"]``);
    motion: (T, C) float64 channel values, C = total channel count; frame_time: seconds;
    end_sites: {joint index: (3,) End Site offset}.
    """

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[list[str]]
    motion: np.ndarray
    frame_time: float
    end_sites: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def fps(self) -> float:
        """1 / frame_time, snapped to the nearest integer when within 0.01 % (0.0083333 s -> 120)."""
        f = 1.0 / self.frame_time
        return float(round(f)) if abs(f - round(f)) < 1e-4 * f else f

    def index(self, name: str) -> int:
        """Index of joint ``name`` (ValueError listing the file's joints if absent)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"joint {name!r} is not in the BVH; it has: {', '.join(self.names)}") from None

    def local_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-joint local rotations (T, J, 3, 3) and translations (T, J, 3) in file units."""
        T, J = self.num_frames, len(self.names)
        R = np.broadcast_to(np.eye(3), (T, J, 3, 3)).copy()
        t = np.broadcast_to(self.offsets, (T, J, 3)).copy()
        col = 0
        for j, chans in enumerate(self.channels):
            rot_axes, rot_cols = [], []
            for k, ch in enumerate(chans):
                axis, kind = ch[0].upper(), ch[1:].lower()
                if kind == "position":
                    t[:, j, _AXES[axis]] = self.motion[:, col + k]
                else:
                    rot_axes.append(axis)
                    rot_cols.append(col + k)
            for axis, c in zip(rot_axes, rot_cols):
                # rotations in channel order: R = R_a1 @ R_a2 @ R_a3 (composed one channel at a time,
                # so any order, even one that repeats an axis, is read)
                R[:, j] = R[:, j] @ Rotation.from_euler(axis.lower(), self.motion[:, c, None], degrees=True).as_matrix()
            col += len(chans)
        return R, t

    def forward_kinematics(self) -> tuple[np.ndarray, np.ndarray]:
        """World joint positions (T, J, 3) and rotations (T, J, 3, 3), file units and axes.

        Loops over joints only; every step is vectorised over frames."""
        R, t = self.local_transforms()
        G = np.empty_like(R)
        P = np.empty_like(t)
        for j in range(len(self.names)):  # parents precede children in a BVH
            p = self.parents[j]
            if p < 0:
                G[:, j], P[:, j] = R[:, j], t[:, j]
            else:
                G[:, j] = G[:, p] @ R[:, j]
                P[:, j] = P[:, p] + (G[:, p] @ t[:, j, :, None])[..., 0]
        return P, G


# ----------------------------------------------------------------------------------------- reading

_CHANNEL_RE = re.compile(r"^[XYZxyz](position|rotation)$", re.IGNORECASE)


def read_bvh(path: str | Path) -> BvhData:
    """Parse any BVH file (hierarchy, offsets, 3- or 6-channel joints, any rotation order, frames).

    Raises FileNotFoundError if ``path`` is missing and ValueError (naming the file and what is
    wrong) if it is a folder, FIFO or device, or malformed or truncated."""
    path = check_input_file(path, "BVH file", "pass the path of a .bvh file")
    text = path.read_text(encoding="utf-8-sig", errors="replace")  # a UTF-8 byte order mark is not content
    m = re.search(r"^\s*MOTION\s*$", text, flags=re.MULTILINE)
    if not text.lstrip().upper().startswith("HIERARCHY"):
        raise ValueError(f"{path} is not a BVH file: it must start with HIERARCHY")
    if m is None:
        raise ValueError(f"{path} has no MOTION section; the file is truncated or not a BVH")
    names, parents, offsets, channels, end_sites = _parse_hierarchy(text[:m.start()], path)
    motion, frame_time = _parse_motion(text[m.end():], path, sum(len(c) for c in channels))
    return BvhData(names, np.asarray(parents, np.int64), np.asarray(offsets, np.float64).reshape(-1, 3),
                   channels, motion, frame_time, end_sites)


def _parse_hierarchy(head: str, path: Path):
    tokens = head.split()
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[list[str]] = []
    end_sites: dict[int, np.ndarray] = {}
    stack: list[int] = []  # joint index per open brace; -2 marks an End Site block
    pending: int | None = None  # joint (or -2) whose '{' is expected next
    i = 1  # skip HIERARCHY

    def need(n: int, what: str) -> list[str]:
        if i + n > len(tokens):
            raise ValueError(f"{path}: hierarchy ends inside {what}; the file is truncated")
        return tokens[i:i + n]

    def floats(vals: list[str], what: str) -> list[float]:
        try:
            return [float(v) for v in vals]
        except ValueError:
            raise ValueError(f"{path}: {what} must be 3 numbers, got {' '.join(vals)!r}") from None

    while i < len(tokens):
        tok = tokens[i]
        up = tok.upper()
        if up in ("ROOT", "JOINT"):
            (name,) = need(2, f"{tok} declaration")[1:]
            if up == "ROOT" and stack:
                raise ValueError(f"{path}: ROOT {name} declared inside another joint")
            if up == "JOINT" and not stack:
                raise ValueError(f"{path}: JOINT {name} appears outside any ROOT")
            if name in names:
                raise ValueError(f"{path}: joint name {name!r} is used twice; joint names must be unique")
            parents.append(stack[-1] if stack else -1)
            if parents[-1] == -2:
                raise ValueError(f"{path}: JOINT {name} is declared inside an End Site")
            names.append(name)
            offsets.append([0.0, 0.0, 0.0])
            channels.append([])
            pending = len(names) - 1
            i += 2
        elif up == "END":
            need(2, "End Site")
            if not stack or stack[-1] < 0:
                raise ValueError(f"{path}: End Site outside a joint")
            pending = -2
            end_owner = stack[-1]
            i += 2
        elif tok == "{":
            if pending is None:
                raise ValueError(f"{path}: unexpected '{{' (token {i})")
            stack.append(pending)
            pending = None
            i += 1
        elif tok == "}":
            if not stack:
                raise ValueError(f"{path}: unbalanced '}}' in the hierarchy")
            stack.pop()
            i += 1
        elif up == "OFFSET":
            vals = floats(need(4, "OFFSET")[1:], "OFFSET")
            if not stack:
                raise ValueError(f"{path}: OFFSET outside a joint")
            if stack[-1] == -2:
                end_sites[end_owner] = np.asarray(vals)
            else:
                offsets[stack[-1]] = vals
            i += 4
        elif up == "CHANNELS":
            (n,) = need(2, "CHANNELS")[1:]
            if not n.isdigit():
                raise ValueError(f"{path}: CHANNELS must be followed by a count, got {n!r}")
            chans = need(2 + int(n), "CHANNELS")[2:]
            if not stack or stack[-1] < 0:
                raise ValueError(f"{path}: CHANNELS outside a joint")
            bad = [c for c in chans if not _CHANNEL_RE.match(c)]
            if bad:
                raise ValueError(f"{path}: joint {names[stack[-1]]!r} declares CHANNELS {n} but {bad} are not channel "
                                 "names (expected [XYZ]position / [XYZ]rotation); the count must match the names listed")
            channels[stack[-1]] = chans
            i += 2 + int(n)
        else:
            raise ValueError(f"{path}: unexpected token {tok!r} in the hierarchy")
    if stack:
        raise ValueError(f"{path}: the hierarchy has {len(stack)} unclosed '{{'; the file is truncated")
    if not names:
        raise ValueError(f"{path}: the hierarchy declares no joints")
    return names, parents, offsets, channels, end_sites


def _parse_motion(body: str, path: Path, n_channels: int) -> tuple[np.ndarray, float]:
    lines = body.strip().splitlines()
    if len(lines) < 2:
        raise ValueError(f"{path}: MOTION needs 'Frames: N' and 'Frame Time: dt' lines; the file is truncated")
    m1 = re.match(r"^\s*Frames:\s*(\d+)\s*$", lines[0], flags=re.IGNORECASE)
    m2 = re.match(r"^\s*Frame\s+Time:\s*([0-9.eE+-]+)\s*$", lines[1], flags=re.IGNORECASE)
    if m1 is None or m2 is None:
        raise ValueError(f"{path}: MOTION must begin with 'Frames: N' and 'Frame Time: dt', got {lines[:2]}")
    n_frames, frame_time = int(m1.group(1)), float(m2.group(1))
    if not (frame_time > 0 and np.isfinite(frame_time)):
        raise ValueError(f"{path}: Frame Time must be positive, got {frame_time}")
    check_fps(1.0 / frame_time, f"{path}: the frame rate (1 / Frame Time {frame_time:g} s)")
    check_frames(n_frames, f"{path}")
    rows = [ln for ln in lines[2:] if ln.strip()]
    if len(rows) < n_frames:
        raise ValueError(f"{path}: header says {n_frames} frames but only {len(rows)} are present; "
                         "the file is truncated (re-export it)")
    rows = rows[:n_frames]
    try:
        flat = np.array(" ".join(rows).split(), dtype=np.float64)
    except ValueError as e:
        raise ValueError(f"{path}: a frame holds a non-numeric value ({e})") from None
    if flat.size != n_frames * n_channels:
        counts = [len(r.split()) for r in rows]
        bad = next(k for k, c in enumerate(counts) if c != n_channels)
        raise ValueError(f"{path}: frame {bad} has {counts[bad]} values but the hierarchy declares "
                         f"{n_channels} channels; the file is corrupt or truncated")
    motion = flat.reshape(n_frames, n_channels)
    if not np.isfinite(motion).all():
        raise ValueError(f"{path}: the motion holds NaN or inf values")
    return motion, frame_time


# ----------------------------------------------------------------------------------------- writing

def write_bvh(path: str | Path, rot: np.ndarray, root: np.ndarray, offsets: np.ndarray, fps: float) -> None:
    """Write our skeleton's motion as BVH (metres, y-up, ZXY Euler degrees; see the module docstring).

    rot: (T, 24, 3, 3) local rotations; root: (T, 3) pelvis positions, m, z-up world;
    offsets: (24, 3) rest offsets (m); fps: frames per second."""
    rot = np.asarray(rot, np.float64)
    root = np.asarray(root, np.float64)
    offsets = np.asarray(offsets, np.float64)
    if rot.ndim != 4 or rot.shape[1:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"rot must be (T, 24, 3, 3), got {rot.shape}")
    if root.shape != (rot.shape[0], 3):
        raise ValueError(f"root must be ({rot.shape[0]}, 3), got {root.shape}")
    if offsets.shape != (NUM_JOINTS, 3):
        raise ValueError(f"offsets must be (24, 3), got {offsets.shape}")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    C = Y_UP_FROM_Z_UP
    rb = C @ rot @ C.T  # (T, 24, 3, 3) in the y-up frame
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal-lock notices: the matrix is still reproduced
        eul = Rotation.from_matrix(rb.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True).reshape(-1, NUM_JOINTS, 3)
    pos = root @ C.T
    off = offsets @ C.T
    lines = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        ind = "\t" * depth
        kind = "ROOT" if j == 0 else "JOINT"
        lines.append(f"{ind}{kind} {JOINT_NAMES[j]}")
        lines.append(f"{ind}{{")
        o = off[j]
        lines.append(f"{ind}\tOFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        if j == 0:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation")
        else:
            lines.append(f"{ind}\tCHANNELS 3 Zrotation Xrotation Yrotation")
        kids = children(j)
        for c in kids:
            emit(c, depth + 1)
        if not kids:  # End Site: half the joint's own bone further on (at least 5 cm)
            n = np.linalg.norm(off[j])
            e = off[j] / n * max(0.05, 0.5 * n) if n > 1e-9 else np.array([0.0, 0.05, 0.0])
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {e[0]:.6f} {e[1]:.6f} {e[2]:.6f}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(0, 0)
    # channel order per frame: root position, then each joint's (Z, X, Y) in depth-first order
    order = _depth_first()
    values = np.concatenate([pos[:, None, :], eul[:, order]], axis=1).reshape(len(rot), -1)
    lines += ["MOTION", f"Frames: {len(rot)}", f"Frame Time: {1.0 / fps:.8f}"]
    body = "\n".join(lines) + "\n" + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in values) + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(body))


def _depth_first() -> list[int]:
    out: list[int] = []

    def rec(j: int) -> None:
        out.append(j)
        for c in children(j):
            rec(c)
    rec(0)
    return out
