"""BVH files of any skeleton as trumans Sequences (24 joints, metres, z-up): joints mapped by name
(``joint_maps``), rotations kept for our own exports and fitted otherwise. The file format itself
(reading, the channel conventions, our writer) is ``trumans.bvh``."""
from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np

from trumans.bvh import Y_UP_FROM_Z_UP, BvhData, read_bvh
from trumans.importers.joint_maps import (guess_unit_scale, map_joints, place_on_floor, retarget_joints,
                                          sequence_from_joints)
from trumans.resample import resample_sequence
from trumans.rotations import matrix_to_6d
from trumans.sequence import Sequence
from trumans.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS

__all__ = ["import_bvh"]


def import_bvh(
    path: str | Path,
    joint_map: dict[str, str] | None = None,
    unit_scale: float | None = None,
    up: Literal["y", "z"] = "y",
    fps: float | None = None,
    refine_steps: int = 30,
    skeleton: str | None = "auto",
    feet_on_floor: bool = False,
) -> Sequence:
    """Read a BVH of any skeleton as a trumans Sequence (24 joints, metres, z-up, rotations + root_pos).

    joint_map: {our_joint_name: bvh_joint_name} overriding the skeleton map; skeleton: a built-in
    map of ``trumans.importers.joint_maps.SKELETON_MAPS`` ("daz", "cmu_mb"), "auto" (detected) or
    None (the ``DEFAULT_JOINT_MAP`` candidates); End Sites are joints ``<joint>_end``. Absent collars /
    spine joints (or ones sitting on their parent) are interpolated along the chain and absent
    index1 joints are placed beyond the wrist along the forearm. unit_scale: metres per file unit
    (None: guessed from the skeleton's height among m / cm / mm / inch / CMU units). up: the file's
    up axis ('y': ``(x, y, z)_ours = (Z, X, Y)_file``, the inverse of ``write_bvh``). fps: resample
    to this rate (None keeps the file's). feet_on_floor: move the motion vertically so the feet
    stand on z = 0 (without it, feet more than 10 cm off the floor raise a warning). Files whose
    skeleton is exactly ours (``write_bvh``) keep their rotations; others are fitted with
    ``trumans.ik.fit.fit_rotations``, and the fit's error (m) is stored in ``extra["ik_error_mean"]``
    / ``extra["ik_error_max"]``. The rest offsets (24, 3) m that the rotations go with are
    ``extra["offsets"]``: ``forward_kinematics(rotations, root_pos, extra["offsets"])`` gives the joints."""
    if up not in ("y", "z"):
        raise ValueError(f"up must be 'y' or 'z', got {up!r}")
    if unit_scale is not None and not (np.isfinite(unit_scale) and unit_scale > 0):
        raise ValueError(f"unit_scale must be a positive number of metres per file unit, got {unit_scale}")
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps}")
    bvh = read_bvh(path)
    if bvh.num_frames == 0:
        raise ValueError(f"{path} holds no frames")
    Pw, Gw = bvh.forward_kinematics()
    ends = sorted(bvh.end_sites)
    names = bvh.names + [f"{bvh.names[j]}_end" for j in ends]
    if ends:  # End Sites as joints "<joint>_end"
        E = np.stack([Pw[:, j] + Gw[:, j] @ bvh.end_sites[j] for j in ends], axis=1)
        Pw = np.concatenate([Pw, E], axis=1)
    # file axes -> ours: y-up files use (x, y, z) = (X, -Z, Y) (trumans.rotations.Y_UP_TO_Z_UP); z-up files as they are
    C = Y_UP_FROM_Z_UP.T if up == "y" else np.eye(3)
    Pw = Pw @ C.T
    if unit_scale is None:
        rest, _ = BvhData(bvh.names, bvh.parents, bvh.offsets, [[] for _ in bvh.names],
                          np.zeros((1, 0)), 1.0).forward_kinematics()
        pts = np.concatenate([rest[0], [rest[0, j] + e for j, e in bvh.end_sites.items()]]) @ C.T
        unit_scale = guess_unit_scale(float(np.ptp(pts[:, 2])))
    Pw = Pw * unit_scale
    P = retarget_joints(names, Pw, joint_map, skeleton)
    src = map_joints(names, joint_map, skeleton)
    ours = len(bvh.names) == NUM_JOINTS and all(v is not None and v < len(bvh.names) for v in src.values()) and all(
        bvh.parents[src[n]] == src[JOINT_NAMES[PARENTS[j]]] for j, n in enumerate(JOINT_NAMES) if j > 0)
    if ours:  # our own export: keep the file's rotations exactly
        rot = C @ Gw[:, [src[n] for n in JOINT_NAMES]] @ C.T  # global, our axes
        rot[:, 1:] = np.swapaxes(rot[:, PARENTS[1:]], -1, -2) @ rot[:, 1:]  # global -> local
        off = np.asarray(bvh.offsets, np.float64)[[src[n] for n in JOINT_NAMES]] @ C.T * unit_scale
        seq = Sequence(joints=P.astype(np.float32), fps=bvh.fps, rotations=matrix_to_6d(rot).astype(np.float32),
                       root_pos=P[:, 0].astype(np.float32), extra={"offsets": off.astype(np.float32)})
        if fps is not None and abs(fps - bvh.fps) > 1e-6:
            seq = resample_sequence(seq, fps)
    else:
        seq = sequence_from_joints(P, bvh.fps, target_fps=fps, refine_steps=refine_steps)
    return place_on_floor(seq, feet_on_floor, source=str(path))
