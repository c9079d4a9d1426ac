"""Scripted activities in procedural rooms: lying on beds and sofas, opening doors, planted feet."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.scenes.occupancy import scene_occupancy
from trumans.scenes.procedural import make_room
from trumans.scenes.io import save_scene
from trumans.contacts.rule import CONTACT_THRESHOLD, JOINT_RADIUS, contact_rule
from trumans.skeleton import JOINT_INDEX as J
from trumans.skeleton import forward_kinematics
from trumans.eval import metrics
from trumans.synth import lying, posture
from trumans.synth.locomotion import foot_places
from trumans.synth.activities import ACTIVITIES
from trumans.synth.activity_furniture import MIN_DOOR_ANGLE
from trumans.synth.moves import MAX_PENETRATION, idle
from trumans.synth.room import RoomContext
from trumans.synth.take import Skip, TakeState, draw_actor


def _context(tmp_path, seed: int, furniture: list[str], size=(5.0, 5.0)) -> RoomContext:
    scene = make_room(seed, size=size, furniture=furniture)
    save_scene(scene, tmp_path)
    return RoomContext.build(scene, scene_occupancy(scene, tmp_path), 30.0)


def _perform(ctx: RoomContext, activity: str, name: str, seed: int) -> TakeState | None:
    """Run one activity from a random walkable spot; None when it was skipped as infeasible."""
    rng = np.random.default_rng(seed)
    cells = np.argwhere(ctx.plans[0].walkable)
    st = TakeState(offsets=draw_actor(rng), speed=1.1, pos=ctx.plans[0].centers(cells[rng.integers(len(cells))]),
                   yaw=float(rng.uniform(-np.pi, np.pi)),
                   poses={n: o.pose.copy() for n, o in ctx.scene.objects.items() if o.dynamic})
    st.append(idle(ctx, st, rng))
    try:
        ACTIVITIES[activity].run(ctx, st, rng, name)
    except Skip:
        return None
    return st


def _labelled(st: TakeState, label: str) -> np.ndarray:
    """Frames (of the concatenated parts) of the parts labelled ``label``."""
    out, t = [], 0
    for p in st.parts:
        if p.actions[0].name == label:
            out.append(np.arange(t, t + p.num_frames))
        t += p.num_frames
    return np.concatenate(out) if out else np.zeros(0, dtype=int)


@pytest.mark.parametrize("kind", ["bed", "sofa"])
def test_lying_on_a_bed_or_sofa_happens_on_its_surface(tmp_path, kind):
    ctx = _context(tmp_path, 3, [kind])
    obj = next(o for o in ctx.scene.objects.values() if o.category == kind)
    done = [st for st in (_perform(ctx, "lie", obj.name, s) for s in range(3)) if st is not None]
    assert len(done) >= 2  # lying is regularly possible (a rare actor may not fit a short sofa)
    h = float(obj.meta["lie_center"][2])
    inv = np.linalg.inv(obj.pose)
    for st in done:
        names = [p.actions[0].name for p in st.parts]
        i = names.index("sit_down")
        assert names[i:i + 5] == ["sit_down", "lie_down", "lie", "get_up", "stand_up"]
        m = st.motion()
        joints, G = forward_kinematics(m.rot, m.root, m.offsets)
        lie = _labelled(st, "lie")
        pel = joints[lie, J["pelvis"]]
        # The pelvis rests on the mattress / cushion: at its height above the surface, over it.
        clear = posture.seat_clearance(m.offsets)
        assert (pel[:, 2] > h + clear - 0.01).all() and (pel[:, 2] < h + clear + 0.05).all()
        loc = pel @ inv[:3, :3].T + inv[:3, 3]
        lo, hi = obj.mesh.bounds
        assert ((loc[:, :2] > lo[:2] + 0.1) & (loc[:, :2] < hi[:2] - 0.1)).all()
        # The trunk lies flat along the lying direction.
        spine = joints[lie, J["neck"]] - pel
        assert (np.abs(spine[:, 2]) / np.linalg.norm(spine, axis=1) < 0.15).all()
        # Nothing goes deep into the furniture over the whole activity (lying down, getting up).
        res = ctx.contacts.query(joints, {})
        pen = contact_rule(joints, res, global_rot=G).penetration
        assert pen.max() < MAX_PENETRATION + 1e-6


def test_short_sofa_is_lain_on_with_the_knees_up():
    off = draw_actor(np.random.default_rng(0))
    head, feet = lying.lying_extent(off)
    length = head + feet - 0.2  # 20 cm too short to lie straight
    shift, reach = lying.fit_lying(off, length)
    assert reach is not None and reach >= lying.min_leg_reach(off)
    h2, f2 = lying.lying_extent(off, reach)
    assert shift + h2 <= length / 2 + 1e-6 and shift - f2 >= -length / 2 - 1e-6  # fits between the ends
    centre = np.array([1.0, 2.0, 0.42])
    rot, root = lying.lying_state(off, centre, 0.3, reach)
    P, _ = forward_kinematics(rot[None], root[None], off)
    ank = P[0, [J["left_ankle"], J["right_ankle"]]]
    flat = foot_places(off, np.zeros(2), 0.0)[:, 2]  # ankle height of a flat foot on the floor
    np.testing.assert_allclose(ank[:, 2], centre[2] + flat, atol=1e-3)  # feet flat on the cushion
    assert (P[0, [J["left_knee"], J["right_knee"]], 2] > centre[2] + 0.2).all()  # knees up
    with pytest.raises(ValueError, match="too short"):
        lying.fit_lying(off, 1.0)


def test_door_is_pulled_open_wide_with_the_hand_on_the_handle(tmp_path):
    ctx = _context(tmp_path, 4, ["table"])
    door = ctx.scene.objects[ctx.scene.meta["door"]]
    done = [st for st in (_perform(ctx, "door", door.name, s) for s in range(3)) if st is not None]
    assert len(done) >= 2
    for st in done:
        names = [p.actions[0].name for p in st.parts]
        assert "open_door" in names and "close_door" in names
        tr = st.object_tracks(ctx)[door.name]
        rel = np.linalg.inv(door.pose) @ tr
        ang = np.arctan2(rel[:, 1, 0], rel[:, 0, 0]) * door.meta["open_sign"]
        assert ang.max() >= MIN_DOOR_ANGLE - 1e-6  # a useful opening
        assert abs(ang[-1]) < 1e-9  # closed again
        take = st.finish(ctx)
        assert len(take.grasp_gaps) > 30 and take.grasp_gaps.max() < 0.03  # the palm stays on the handle
        assert take.penetration.max() < MAX_PENETRATION + 1e-6
    # A failed activity is rolled back: appending the door opening again moves the door, restoring
    # the snapshot puts the state (parts, frames, position, heading, object poses, grasps) back.
    st = done[0]
    opening = next(p for p in st.parts if p.actions[0].name == "open_door")
    before = st.snapshot()
    n, frames, pos, yaw, grasped = len(st.parts), st.frames, st.pos.copy(), st.yaw, len(st.grasped)
    closed = st.poses[door.name].copy()
    st.append(opening, {w: door.name for w in opening.grasp})
    assert st.frames == frames + opening.num_frames and len(st.grasped) == grasped + 1
    assert not np.allclose(st.poses[door.name], closed)  # left open
    st.restore(before)
    assert (len(st.parts), st.frames, st.yaw, len(st.grasped)) == (n, frames, yaw, grasped)
    np.testing.assert_array_equal(st.pos, pos)
    np.testing.assert_array_equal(st.poses[door.name], closed)
    assert st.motion().num_frames == frames


def test_turns_and_walks_keep_floor_contacts_planted(tmp_path):
    """Foot skate as the builder measures it (the foot joint within the contact band of the floor)
    stays far below the 2 cm target for a take of walks and turns in a room."""
    ctx = _context(tmp_path, 1, ["table"], size=(6.0, 6.0))
    rng = np.random.default_rng(2)
    st = TakeState(offsets=draw_actor(rng), speed=1.2, pos=np.array([1.5, 1.5]), yaw=0.0,
                   poses={n: o.pose.copy() for n, o in ctx.scene.objects.items() if o.dynamic})
    st.append(idle(ctx, st, rng))
    for _ in range(6):
        try:
            ACTIVITIES["wander"].run(ctx, st, rng, "")
        except Skip:
            continue
    take = st.finish(ctx)
    names = {a.name for p in st.parts for a in p.actions}
    assert {"walk", "turn"} <= names
    feet = take.sequence.joints[:, [J["left_foot"], J["right_foot"]]]
    slides = metrics.foot_slides(feet, take.foot_floor)
    assert len(slides) > 20
    assert slides.mean() < 0.005 and slides.max() < 0.02
    # The builder's floor contact is the contact band of the foot joint.
    band = feet[..., 2] < JOINT_RADIUS[J["left_foot"]] + CONTACT_THRESHOLD
    assert (take.foot_floor <= band).all()

