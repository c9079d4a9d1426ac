"""The swept guard's slide (trumans.sample.cleanup.swept): a body that the network drives along a wall and a
little into it walks on along the wall at the depth cap instead of freezing there (the safety benchmark's
unfinished wall plans); the contact depth it caps off the feet (trumans.eval.safety.contact_depths); the
benchmark's --only-plans."""
import numpy as np
import pytest
from helpers import standing_body

from trumans.eval.safety import contact_depths, core_depths, crossings
from trumans.sample.cleanup.swept import SweptGuardConfig, guard_crossings
from trumans.sample.eval_safety import parse_only_plans
from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.sdf import SceneSDF
from trumans.skeleton import JOINT_INDEX

PELVIS, ANKLE = JOINT_INDEX["pelvis"], JOINT_INDEX["left_ankle"]


def _wall_sdf() -> SceneSDF:
    origin = np.array([0.01, 0.01, -0.09])
    x, y, z = np.meshgrid(*(origin[i] + 0.02 * np.arange(n) for i, n in enumerate((120, 200, 120))), indexing="ij")
    return SceneSDF(OccupancyGrid((z < 0) | (x > 1.5), origin, 0.02))  # a wall beyond x = 1.5


def _walk_into_wall(sdf: SceneSDF, T: int = 14) -> np.ndarray:
    """(1, T, 24, 3): standing bodies walking +y along the wall, 10 cm a frame, drifting 3 mm a frame into it (4 cm in all);
    frame 0 has its deepest joint 1.5 cm deep (under the 2 cm cap)."""
    J = standing_body(T)
    J[..., 1] += (1.0 + 0.1 * np.arange(T) - J[0, :, PELVIS, 1])[:, None]
    J[..., 0] += 1.0 - J[0, 0, PELVIS, 0]
    x0 = 1.0
    for _ in range(60):  # bisect the start so that the deepest joint is 1.5 cm deep
        d = core_depths(J[0, :1] + [x0 - 1.0, 0, 0], sdf).max()
        x0 += 0.5 * (0.015 - d) if d > 0 else 0.02
    J[..., 0] += (x0 - 1.0) + 0.003 * np.arange(T)[None, :, None]
    return J


def test_a_body_driven_into_a_wall_slides_along_it_instead_of_freezing():
    sdf = _wall_sdf()
    J = _walk_into_wall(sdf)
    T, k = J.shape[1], 2
    up = np.ones((1, T))
    cap = SweptGuardConfig().max_depth
    assert core_depths(J[0], sdf).max() > cap + 0.02  # the network's frames go 2+ cm past the cap
    out = guard_crossings(J, sdf, k, weight=up)
    old = guard_crossings(J, sdf, k, SweptGuardConfig(slide_iters=0), weight=up)
    assert core_depths(out[0, k:], sdf).max() <= cap + 1e-3 and not crossings(out[0], sdf).any()
    walked = out[0, -1, PELVIS, 1] - out[0, k - 1, PELVIS, 1]
    assert walked > 0.9 * (J[0, -1, PELVIS, 1] - J[0, k - 1, PELVIS, 1])  # it walks on along the wall
    assert old[0, -1, PELVIS, 1] - old[0, k - 1, PELVIS, 1] < 0.5 * walked  # the blend alone stalls at the cap
    np.testing.assert_allclose(out[0, k:, 1:] - out[0, k:, :1], J[0, k:, 1:] - J[0, k:, :1], atol=1e-9)  # rigid
    assert np.abs(out[0, k:, :, 2] - J[0, k:, :, 2]).max() < 1e-9  # upright: slid horizontally only


def test_contact_depth_uses_the_contact_radius_where_the_surface_faces_the_joint():
    origin = np.array([-0.49, -0.49, -0.09])
    x, y, z = np.meshgrid(*(origin[i] + 0.02 * np.arange(n) for i, n in enumerate((50, 50, 60))), indexing="ij")
    sdf = SceneSDF(OccupancyGrid(z < 0.4, origin, 0.02))  # a slab whose top is at 0.4 m
    J = standing_body(1)[0]
    J = J - J[:, ANKLE][:, None] + np.array([0.0, 0.0, 0.46])  # the ankle 6 cm over the slab: heel 2.5 cm in
    core, contact = core_depths(J, sdf), contact_depths(J, sdf)
    assert (contact >= core - 1e-9).all()
    assert core[0, ANKLE] == 0.0  # 3.5 cm core radius: clear
    assert contact[0, ANKLE] == pytest.approx(0.085 - 0.06, abs=0.012)  # 8.5 cm toward the surface below


def test_only_plans_is_parsed_and_bad_values_are_refused():
    assert parse_only_plans(None, 50, True) == (None, True)
    assert parse_only_plans("45, 10,demo", 50, False) == ({45, 10}, True)
    assert parse_only_plans("3", 50, True) == ({3}, False)
    for bad in ("50", "x", "", "-1"):
        with pytest.raises(ValueError, match="--only-plans"):
            parse_only_plans(bad, 50, False)


def test_a_sofa_with_a_cabinet_before_its_head_end_is_lain_on_the_other_way():
    """Eval room 9005: a cabinet stands in front of the sofa's lie_yaw end (plan 13 of the safety benchmark put the
    head into its drawer); the plan lies the other way and sits down on the edge at the free end."""
    from trumans.sample.controller import compile_plan, free_margin, lie_head_flipped, lie_heading
    from trumans.sample.plan import plan_from_dict
    from trumans.sample.scene_input import load_sample_scene

    sc = load_sample_scene("room:9005")
    sofa, fm = sc.scene.objects["sofa_0"], free_margin(sc.walkmap)

    def free_at(p):
        i = np.clip(sc.walkmap.index(p), 0, np.asarray(fm.shape) - 1)
        return float(fm[i[0], i[1]])

    assert lie_head_flipped(sofa, sc.walkmap, free_at)
    assert not lie_head_flipped(sc.scene.objects["table_0"], sc.walkmap, free_at)
    phases = compile_plan(plan_from_dict({"steps": [{"do": "lie_on", "object": "sofa_0", "seconds": 2}]}), sc.scene,
                          sc.walkmap, sc.free_point(), {}, 10.0, vocabulary=("walk", "turn", "sit_down", "lie_down", "lie"))
    lying = [p for p in phases if p.kind in ("lie_down", "lie")]
    assert all(np.isclose(np.cos(p.heading - lie_heading(sofa, True)), 1.0) for p in lying)
    seat = next(p for p in phases if p.kind == "sit_down").goal
    cabinet = sc.scene.objects["cabinet_0"].pose[:2, 3]
    assert np.linalg.norm(seat - cabinet) > 1.0  # the edge seat at the end away from the cabinet
