"""Figures of the moved objects (``trumans.sample.carry``): how well the hand holds them and where they end.

- ``hoi_hand_obj_dist_cm`` / ``hoi_hand_obj_dist_std_cm``: mean / std over the contact frames of
  the distance from the middle of the holding hand (``hand_points``) to the object's surface; the
  same with ``_static`` (the object left where it was: what the output had before objects moved)
  and ``_init`` (the hand-driven initial motion, before the §4.2 optimisation);
- ``hoi_rel_std_cm``: the optimised quantity, sqrt of the variance of the hand points in the
  object frame (and ``_init``);
- ``hoi_obj_acc_cm`` (and ``_init``): mean acceleration of the object's origin over the contact,
  cm per frame^2 (the smoothness the optimisation adds);
- ``hoi_obj_penetration_max_cm``: deepest object vertex inside the scene (static meshes, the other
  objects where they are) or under the floor, over every frame;
- ``hoi_place_err_cm``: distance of a put-down object's grasp point from the plan's put-down hand
  goal; ``hoi_float_cm``: gap between its bottom and the support under it at the end.
"""
from __future__ import annotations

import numpy as np
import trimesh

from trumans.scenes.distance import SceneDistance
from trumans.track.objects import hand_points

from trumans.sample.carry import Interaction, hand_track, put_down_pose

__all__ = ["carry_figures"]


def _surface_dist(obj, poses: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Distance (n,) of world points p (n, 3) to the object's surface at poses (n, 4, 4)."""
    local = np.einsum("nji,nj->ni", poses[:, :3, :3], p - poses[:, :3, 3])
    return np.linalg.norm(trimesh.proximity.closest_point(obj.mesh, local)[0] - local, axis=1)


def _rel_std(poses: np.ndarray, pts: np.ndarray) -> float:
    q = np.einsum("nji,nkj->nki", poses[:, :3, :3], pts - poses[:, None, :3, 3])
    return float(np.sqrt(((q - q.mean(0)) ** 2).sum(-1).mean()))


def _penetration(scene, name: str, track: np.ndarray, tracks: dict, stride: int = 2) -> float:
    obj = scene.objects[name]
    v = np.asarray(obj.mesh.vertices)
    v = v[np.linspace(0, len(v) - 1, min(len(v), 150)).astype(int)]
    frames = np.arange(0, len(track), stride)
    others = {k: m for k, m in scene.static.items()}
    moved = {n for n in tracks if n != name}
    others |= {n: o.world_mesh() for n, o in scene.objects.items() if n != name and n not in moved}
    w = np.einsum("nij,pj->npi", track[frames, :3, :3], v) + track[frames, None, :3, 3]
    depth = np.maximum(0.0, -w[..., 2])  # under the floor
    d = SceneDistance(others).query(w.reshape(-1, 3)).signed.reshape(w.shape[:2]) if others else np.zeros(w.shape[:2])
    depth = np.maximum(depth, np.maximum(0.0, -d))
    return float(depth.max())


def carry_figures(joints: np.ndarray, tracks: dict, its: list[Interaction], info: dict, scene,
                  phases: list) -> dict:
    """Figures of one sample (module doc); ``info``: the third output of ``object_tracks``.
    ``hoi_grasps_reached`` / ``hoi_grasps_missed``: grasps the body reached / did not reach (with
    ``hoi_missed_dist_cm``, the closest wrist distance of the missed ones). Distances in cm."""
    missed = info["missed"]
    head = {"hoi_grasps_reached": len(its), "hoi_grasps_missed": len(missed)}
    if missed:
        head["hoi_missed_dist_cm"] = round(100 * float(np.mean([d for _, d in missed])), 2)
    if not its:
        return head if missed else {}
    inits = info["init"]
    joints = np.asarray(joints, np.float64)
    out: dict[str, list[float]] = {}
    side = {"left_wrist": 0, "right_wrist": 1}
    for it in its:
        obj = scene.objects[it.name]
        f = np.arange(it.start, it.end + 1)
        pose = np.asarray(tracks[it.name].pose, np.float64)[f]
        init = next(p for s, p in inits[it.name] if s == it.start)
        mid = hand_points(joints[f])[:, side[it.hand]]
        pts, _ = hand_track(joints[f], it.hand)
        for key, P in (("", pose), ("_init", init), ("_static", np.broadcast_to(pose[0], pose.shape))):
            d = _surface_dist(obj, np.asarray(P), mid)
            out.setdefault(f"hoi_hand_obj_dist_cm{key}", []).append(100 * d.mean())
            out.setdefault(f"hoi_hand_obj_dist_std_cm{key}", []).append(100 * d.std())
        for key, P in (("", pose), ("_init", init)):  # mean acceleration of the object's centre, cm / frame^2
            c = np.asarray(P)[:, :3, 3]
            out.setdefault(f"hoi_obj_acc_cm{key}", []).append(
                100 * float(np.linalg.norm(c[2:] - 2 * c[1:-1] + c[:-2], axis=1).mean()) if len(c) > 2 else 0.0)
        out.setdefault("hoi_rel_std_cm", []).append(100 * _rel_std(pose, pts))
        out.setdefault("hoi_rel_std_cm_init", []).append(100 * _rel_std(init, pts))
        if it.placed:
            goal = next(p.hand_goal for p in phases if p.info.get("do") == "put_down" and p.info["object"] == it.name)
            final = pose[-1]
            grasp = final[:3, :3] @ np.asarray(obj.meta.get("grasp_point", [0, 0, 0]), np.float64) + final[:3, 3]
            out.setdefault("hoi_place_err_cm", []).append(100 * float(np.linalg.norm(grasp - goal)))
            supports = list(scene.static.values()) + [o.world_mesh() for n, o in scene.objects.items() if n != it.name]
            out.setdefault("hoi_float_cm", []).append(100 * abs(put_down_pose(obj, final, supports)[2, 3] - final[2, 3]))
    pen = [_penetration(scene, n, np.asarray(t.pose, np.float64), tracks) for n, t in tracks.items()]
    res = {k: round(float(np.mean(v)), 2) for k, v in out.items()}
    res["hoi_obj_penetration_max_cm"] = round(100 * max(pen), 2)
    return {**head, **res}
