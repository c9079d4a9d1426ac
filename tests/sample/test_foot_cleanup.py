"""Foot cleanup of sampled episodes (trumans.sample.cleanup.foot): locks, floor, bone lengths, context."""
import numpy as np
import pytest
import torch

from trumans.ik.limb import two_bone_positions
from trumans.sample.cleanup.foot import FootCleanupConfig, clean_feet, foot_contacts, support_foot
from trumans.skeleton import LEG_CHAINS
from trumans.sample.sampler import bone_lengths_of
from trumans.eval.synthesis_metrics import floor_err_cm, foot_skate_near_floor_cm
from trumans.skeleton import rest_offsets, forward_kinematics

from helpers import box_room, standing_body

FPS = 30.0


def _sliding_planted_foot(T: int = 40) -> np.ndarray:
    """Standing body whose whole left leg slides 1 cm/frame forward and sinks 3 cm (a skating foot)."""
    J = standing_body(T)
    left = list(LEG_CHAINS[0][1:])
    J[0, :, left, 0] += 0.01 * np.arange(T)[:, None]
    J[0, :, left, 2] -= 0.03
    return J  # the left shin and thigh are not rigid any more: the hip->knee bone changes length


def test_two_bone_positions_keeps_lengths_and_reaches():
    rng = np.random.default_rng(0)
    hip = rng.normal(size=(50, 3))
    knee = hip + rng.normal(size=(50, 3)) * 0.3
    target = hip + rng.normal(size=(50, 3)) * 0.4
    k, a = two_bone_positions(hip, knee, target, 0.42, 0.40)
    np.testing.assert_allclose(np.linalg.norm(k - hip, axis=-1), 0.42, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(a - k, axis=-1), 0.40, atol=1e-9)
    inside = np.linalg.norm(target - hip, axis=-1) < 0.81
    np.testing.assert_allclose(a[inside], target[inside], atol=1e-9)


def test_contacts_have_hysteresis():
    J = np.repeat(standing_body(1), 30, axis=1)
    ankle, toe = LEG_CHAINS[0][2:]
    lift = np.r_[np.zeros(10), np.full(5, 0.08), np.full(5, 0.2), np.full(10, 0.08)]  # 0.08: between thresholds
    J[:, :, [ankle, toe], 2] += lift[:, None]
    c = foot_contacts(J, FPS)[0, :, 0]
    assert c[:15].all()  # 0.08 m up keeps an existing contact
    assert not c[15:].any()  # 0.2 m leaves it and 0.08 m does not re-enter
    assert foot_contacts(J, FPS)[0, :, 1].all()


def test_clean_feet_pins_planted_foot_and_keeps_bones():
    J = standing_body(40)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEG_CHAINS[0][2:]
    moved = J.copy()  # the whole body slides forward 6 cm/s and sinks 3 cm: both feet skate under the floor
    moved[..., 0] += 0.002 * np.arange(40)[:, None]
    moved[..., 2] -= 0.03
    low = np.minimum(moved[0, :, ankle, 2] - 0.08, moved[0, :, toe, 2] - 0.04)
    assert foot_skate_near_floor_cm(moved[0]) > 5 and low.min() < -0.005  # skating and under the floor
    out = clean_feet(moved, lengths, FPS, fixed=0)
    np.testing.assert_allclose(bone_lengths_of(out[0])[:, 1:], np.broadcast_to(lengths[1:], (40, 23)), atol=1e-6)
    assert np.ptp(out[0, :, ankle, :2], axis=0).max() < 1e-6  # pinned where it landed
    low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, toe, 2] - 0.04)
    np.testing.assert_allclose(low, 0.0, atol=1e-6)  # on the floor, not under it
    assert floor_err_cm(out[0])[1] < 1e-4
    assert foot_skate_near_floor_cm(out[0]) < 0.1
    untouched = [j for j in range(24) if j not in LEG_CHAINS[0][1:] + LEG_CHAINS[1][1:]]
    np.testing.assert_array_equal(out[..., untouched, :], moved[..., untouched, :])


def test_context_frames_are_fixed_and_seed_the_lock():
    J = standing_body(30)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEG_CHAINS[1][2:]
    moved = J.copy()
    moved[:, 10:, [ankle, toe], 1] += 0.005 * np.arange(1, 21)[:, None]  # the new frames drift the planted foot
    out = clean_feet(moved, lengths, FPS, fixed=10)
    np.testing.assert_array_equal(out[:, :10], moved[:, :10])
    np.testing.assert_allclose(out[0, 10:, ankle, :2], np.broadcast_to(moved[0, 9, ankle, :2], (20, 2)), atol=1e-4)


def test_swing_foot_is_left_free_and_bad_input_raises():
    J = np.repeat(standing_body(1), 20, axis=1)
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEG_CHAINS[0][2:]
    J[:, :, [ankle, toe], 0] += 0.05 * np.arange(20)[:, None]  # 1.5 m/s, a step in the air
    J[:, :, [ankle, toe], 2] += 0.15
    out = clean_feet(J, lengths, FPS)
    np.testing.assert_allclose(out, J, atol=1e-9)
    with pytest.raises(ValueError, match="joints must be"):
        clean_feet(J[0], lengths, FPS)
    with pytest.raises(ValueError, match="fixed"):
        clean_feet(J, lengths, FPS, fixed=99)
    with pytest.raises(ValueError, match="enter_height"):
        FootCleanupConfig(enter_height=0.2, exit_height=0.1)


def _crouched(T: int) -> np.ndarray:
    """(1, T, 24, 3) standing with bent knees (facing +x), lowest foot joint at its rest height."""
    from scipy.spatial.transform import Rotation

    rot = np.broadcast_to(np.eye(3), (T, 24, 3, 3)).copy()
    for (hip, knee, ankle, _), bend in zip(LEG_CHAINS, (1.0, 1.0)):
        rot[:, hip] = Rotation.from_rotvec([0.0, -0.35 * bend, 0.0]).as_matrix()
        rot[:, knee] = Rotation.from_rotvec([0.0, 0.7 * bend, 0.0]).as_matrix()
        rot[:, ankle] = Rotation.from_rotvec([0.0, -0.35 * bend, 0.0]).as_matrix()
    P, _ = forward_kinematics(rot, np.zeros((T, 3)), rest_offsets())
    L, R = LEG_CHAINS[0], LEG_CHAINS[1]
    P[..., 2] -= min((P[0, [L[2], R[2]], 2] - 0.08).min(), (P[0, [L[3], R[3]], 2] - 0.04).min())
    return P[None]


def _shuffle_step(T: int = 30) -> np.ndarray:
    """Crouched body whose left foot stands (frames 0-9), shuffles 30 cm forward 1 cm over the
    floor in 7 frames (1.3 m/s, a low swing), and stands again: a step that never leaves the floor."""
    J = _crouched(T)
    ankle, toe = LEG_CHAINS[0][2:]
    x = np.r_[np.zeros(10), np.linspace(0.0, 0.3, 8)[1:-1], np.full(T - 16, 0.3)]
    J[0, :, [ankle, toe], 0] += x[None, :]
    J[0, 10:16, [ankle, toe], 2] += 0.01
    return J


def test_low_swing_between_plants_is_lifted_and_lands_on_its_lock():
    J = _shuffle_step()
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEG_CHAINS[0][2:]
    assert foot_skate_near_floor_cm(J[0]) > 10  # by the benchmark's definition the shuffle is a 40 cm slide
    out = clean_feet(J, lengths, FPS, fixed=0)
    low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, toe, 2] - 0.04)
    assert low[12:15].min() > 0.05  # mid-swing clearance min(0.07, 0.2 x 0.3 m) sin(pi u)
    np.testing.assert_allclose(low[:10], 0.0, atol=1e-6)
    np.testing.assert_allclose(low[17:], 0.0, atol=1e-6)
    np.testing.assert_allclose(out[0, 17:, ankle, 0], J[0, 16, ankle, 0], atol=1e-6)  # lands on its lock
    v = np.linalg.norm(np.diff(out[0, :, ankle, :2], axis=0), axis=-1)
    assert v[9] < 0.02 and v[16] < 0.02  # leaves and lands at rest: no pop at the lock's release
    assert np.abs(np.diff(out[0, :, ankle, 0], n=2)).max() < 0.05  # smooth: no jump anywhere
    assert foot_skate_near_floor_cm(out[0]) < 3.0
    np.testing.assert_allclose(bone_lengths_of(out[0, 10:17])[:, 1:], np.broadcast_to(lengths[1:], (7, 23)), atol=1e-6)
    # swing_height 0 keeps the network's swing height (only the path is smoothed)
    flat = clean_feet(J, lengths, FPS, config=FootCleanupConfig(swing_height=0.0))
    low0 = np.minimum(flat[0, :, ankle, 2] - 0.08, flat[0, :, toe, 2] - 0.04)
    assert low0.max() < 0.02


def test_swing_across_an_episode_seam_rises_then_lands_without_a_jump():
    J = _shuffle_step()
    lengths = bone_lengths_of(J[0, 0])
    ankle, toe = LEG_CHAINS[0][2:]
    first = clean_feet(J[:, :13], lengths, FPS)  # the window ends mid-swing (frames 10-12 in the air)
    second = clean_feet(np.concatenate([first[:, -2:], J[:, 13:]], 1), lengths, FPS, fixed=2)
    out = np.concatenate([first, second[:, 2:]], 1)
    low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, toe, 2] - 0.04)
    assert low[11:16].min() > 0.03 and low[12] > 0.05  # lifted before and after the seam
    np.testing.assert_allclose(low[17:], 0.0, atol=1e-6)
    assert np.abs(np.diff(out[0, :, ankle], axis=0)).max() < 0.08  # m per frame: no jump at the seam
    np.testing.assert_allclose(out[0, 17:, ankle, :2], np.broadcast_to(J[0, 16, ankle, :2], (13, 2)), atol=1e-6)
    assert foot_skate_near_floor_cm(out[0]) < 3.0


def test_support_foot_plants_the_lower_foot_only_when_upright():
    """Both feet sliding fast (no detected contact): the lower one is planted, with hysteresis; a body
    whose hips are low (sitting down) gets no support foot."""
    T = 20
    J = np.repeat(standing_body(1), T, axis=1)
    (_, _, la, lt), (_, _, ra, rt) = LEG_CHAINS[0], LEG_CHAINS[1]
    # left foot 3 cm up for frames 0-9, then 5 cm; the right the other way round (1 cm differences within
    # the margin never switch); both feet slide 3 cm a frame, too fast to count as planted
    J[0, :, la, 2] += np.r_[np.full(10, 0.03), np.full(10, 0.05)]
    J[0, :, lt, 2] += np.r_[np.full(10, 0.03), np.full(10, 0.05)]
    right = np.r_[np.full(10, 0.05), np.full(5, 0.04), np.full(5, 0.02)]
    J[0, :, ra, 2] += right
    J[0, :, rt, 2] += right
    for j in (la, lt, ra, rt):
        J[0, :, j, 0] += 0.03 * np.arange(T)
    assert not foot_contacts(J, FPS).any()
    lengths = bone_lengths_of(J[0, 0])
    leg = lengths[LEG_CHAINS[0][1]] + lengths[LEG_CHAINS[0][2]]
    c = support_foot(foot_contacts(J, FPS), J, float(leg), FPS)[0]
    assert (c.sum(-1) == 1).all()
    assert c[:10, 0].all()  # left lower by 2 cm
    assert c[10:15, 0].all()  # right lower by only 1 cm: the left keeps the support
    assert c[15:, 1].all()  # right lower by 3 cm: switches
    assert not support_foot(foot_contacts(J, FPS), J, float(leg), FPS, fixed=5)[0, :5].any()
    low = J.copy()  # hips 40 % of the leg lower: crouching / sitting down, left to the detected contacts
    low[0, :, [i for i in range(24) if i not in (la, lt, ra, rt)], 2] -= 0.4 * leg
    assert not support_foot(foot_contacts(low, FPS), low, float(leg), FPS).any()


def test_support_removes_flight_phases():
    """Two feet whose free (sliding) spans overlap, as a shuffling network's do, are never both in the
    air after the cleanup with support; without it each swing gets its clearance arc and both lift."""
    T = 30
    J = np.repeat(standing_body(1), T, axis=1)
    (_, _, la, lt), (_, _, ra, rt) = LEG_CHAINS[0], LEG_CHAINS[1]
    t = np.arange(T)
    for (a, b), (t0, t1) in (((la, lt), (6, 20)), ((ra, rt), (3, 17))):  # slides 3 cm a frame over [t0, t1)
        x = 0.03 * np.clip(t - t0, 0, t1 - t0)
        J[0, :, a, 0] += x
        J[0, :, b, 0] += x
    lengths = bone_lengths_of(J[0, 0])

    def lowest(P):  # (T,) the lower foot's lowest joint above its rest height
        return np.stack([np.minimum(P[0, :, a, 2] - 0.08, P[0, :, b, 2] - 0.04) for a, b in ((la, lt), (ra, rt))], -1).min(-1)

    # the feet end 42 cm ahead of the still, straight-legged hips, 8 cm beyond the leg's reach: the
    # support alone is tested here (with reach_passes the out-of-reach locks are released at the end,
    # test_a_lock_out_of_the_legs_reach_ends_its_contact_run)
    assert (lowest(clean_feet(J, lengths, FPS, config=FootCleanupConfig(support=False, reach_passes=0))) > 0.01).any()
    assert (lowest(clean_feet(J, lengths, FPS, config=FootCleanupConfig(support=True, reach_passes=0))) < 0.005).all()


def test_out_of_scene_moves_feet_out_of_furniture_and_keeps_locks():
    """A planted foot 2 cm inside a box's front face moves out along -x until both ankle and toe clear
    their core radii; a lock's frames move together; a foot in the open is untouched; a free foot
    under the top goes up."""
    from trumans.sample.cleanup.foot import out_of_scene
    from trumans.sample.guidance.penetration import SceneSDF

    sdf = SceneSDF(box_room())  # box x in [1.0, 1.4], y in [0.6, 1.4]
    ankle = np.array([[[1.02, 1.0, 0.08]] * 4 + [[0.5, 1.0, 0.08]]])  # (1, 5, 3): a lock of 4 frames, then the open
    toe_off = np.broadcast_to(np.array([0.0, 0.12, -0.04]), ankle.shape)  # the toe points along +y
    r = (0.04, 0.03)
    out = out_of_scene(ankle, toe_off, sdf, r, iters=4)
    d_ankle = sdf(torch.as_tensor(out[0, :4], dtype=torch.float32)).numpy()
    d_toe = sdf(torch.as_tensor(out[0, :4] + toe_off[0, :4], dtype=torch.float32)).numpy()
    assert (d_ankle > r[0] - 0.01).all() and (d_toe > r[1] - 0.01).all()
    assert np.allclose(out[0, :4], out[0, 0]) and (out[0, :4, 0] < 1.0).all()  # moved out the front, together
    np.testing.assert_allclose(out[0, :, 1:], ankle[0, :, 1:])  # along x only; heights kept
    np.testing.assert_array_equal(out[0, 4], ankle[0, 4])
    under_top = np.array([[[1.2, 1.0, 0.97]]])  # a swinging foot 3 cm under the box's top goes up over it
    up = out_of_scene(under_top, np.zeros_like(under_top), sdf, r, free=np.ones((1, 1), bool), iters=4)
    assert up[0, 0, 2] > 1.0 + r[0] - 0.01 and np.allclose(up[0, 0, :2], under_top[0, 0, :2], atol=0.01)


def _shuffling_crouch(T: int = 80, k: int = 2, speed: float = 0.005) -> np.ndarray:
    """A body 5 cm lower than standing (knees bent) sliding forward ``speed`` m/frame over the new
    frames with both feet on the floor (a shuffle: slow enough to count as planted at ``FPS``)."""
    J = standing_body(T)
    feet = [j for leg in LEG_CHAINS for j in leg[2:]]
    J[0, :, [j for j in range(24) if j not in feet], 2] -= 0.05
    J[0, :, :, 0] += speed * np.clip(np.arange(T) - (k - 1), 0, None)[:, None]
    return J


def test_a_lock_out_of_the_legs_reach_ends_its_contact_run():
    """Both feet locked at the last context frame while the hips shuffle on: from the first frame
    where the lock is farther from the hip than thigh + shin, the leg cannot hold it (the IK would
    drag the foot off the lock and up, as in the demo's last second). The run ends there, the foot
    swings on, and no frame holds a foot at its lock out of reach or off the floor."""
    k, T = 2, 80
    J = _shuffling_crouch(T, k)
    lengths = bone_lengths_of(standing_body(1)[0, 0])
    assert foot_contacts(J, FPS)[0, k:].all()  # the network's feet count as planted all along
    out = clean_feet(J, lengths, FPS, fixed=k)
    stuck = clean_feet(J, lengths, FPS, fixed=k, config=FootCleanupConfig(reach_passes=0))
    slack = FootCleanupConfig().reach_slack  # a lock this far beyond the reach still holds, the clamp lifting it as much
    for hip, knee, ankle, toe in LEG_CHAINS:
        reach = lengths[knee] + lengths[ankle]
        lock = J[0, k - 1, ankle] - [0.0, 0.0, min(J[0, k - 1, ankle, 2] - 0.08, J[0, k - 1, toe, 2] - 0.04)]
        dist = np.linalg.norm(J[0, :, hip] - lock, axis=-1)
        first = int(np.argmax(dist > reach + slack))
        assert k < first < T - 10  # the lock leaves the leg's reach inside the window
        held = np.flatnonzero(dist[:first] <= reach - 1e-3)[k:]
        np.testing.assert_allclose(out[0, held, ankle], np.broadcast_to(lock, (len(held), 3)), atol=1e-6)
        np.testing.assert_allclose(out[0, k:first, ankle], np.broadcast_to(lock, (first - k, 3)), atol=slack + 1e-3)
        at_lock = np.linalg.norm(out[0, :, ankle, :2] - lock[:2], axis=-1) < 1e-3
        assert not at_lock[first:].any()  # released where it went out of reach
        low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, toe, 2] - 0.04)
        assert low.max() < 0.08  # a swing's clearance at most
        stretch = lambda P: np.linalg.norm(P[0, first:, ankle] - P[0, first:, hip], axis=-1)  # noqa: E731
        assert stretch(out).min() < reach - 0.05  # the released leg bends again under the body
        assert stretch(stuck).min() > reach - 2e-3  # without the release it is dragged at full stretch
    legs = [j for leg in LEG_CHAINS for j in leg[1:3]]  # the knee and ankle bones, re-solved on every new frame
    np.testing.assert_allclose(bone_lengths_of(out[0, k:])[:, legs], np.broadcast_to(lengths[legs], (T - k, 4)), atol=1e-6)
    with pytest.raises(ValueError, match="reach_passes"):
        FootCleanupConfig(reach_passes=-1)


def test_knee_bent_into_a_wall_turns_outward_with_bone_lengths_kept():
    """A knee 3 cm inside a wall in front of the body turns about the hip-ankle axis until it is its
    core radius clear; hip and ankle stay, both bones keep their lengths; a knee in the open stays."""
    from trumans.sample.cleanup.foot import knee_out_of_scene
    from trumans.sample.guidance.penetration import SceneSDF

    sdf = SceneSDF(box_room())  # box x in [1.0, 1.4], y in [0.6, 1.4], z < 1
    hip = np.array([[[0.80, 1.0, 0.85], [0.30, 1.0, 0.85]]])  # (1, 2, 3): 20 cm from the box, then in the open
    ankle = hip - [0.0, 0.0, 0.70]
    knee = hip + [0.25, 0.0, -0.35]  # bent 25 cm forward: 5 cm into the box's face
    r = 0.045
    outward = np.broadcast_to([0.0, 1.0, 0.0], hip.shape)  # a left knee: outward is +y
    out = knee_out_of_scene(hip, knee, ankle, outward, sdf, r)
    d = sdf(torch.as_tensor(out, dtype=torch.float32)).numpy()
    assert sdf(torch.as_tensor(knee[0, 0], dtype=torch.float32)).item() < 0 and d[0, 0] > r - 0.005
    for a, b in ((hip, out), (out, ankle)):
        np.testing.assert_allclose(np.linalg.norm(a - b, axis=-1), np.linalg.norm(hip - knee, axis=-1) if a is hip
                                   else np.linalg.norm(knee - ankle, axis=-1), atol=1e-9)
    assert out[0, 0, 1] > 1.05 and out[0, 0, 2] == pytest.approx(knee[0, 0, 2])  # turned outward
    np.testing.assert_array_equal(out[0, 1], knee[0, 1])


def _seated_body(T: int, lengths: np.ndarray, stagger: np.ndarray) -> np.ndarray:
    """(1, T, 24, 3): the standing body lowered onto a 0.5 m seat, thighs horizontal along +y (the
    rest pose's front; checked below) and shins vertical, the left foot ``stagger`` (T,) m ahead of
    where it sits beside the right one; feet on the floor."""
    J = standing_body(T)
    fwd = np.array([0.0, 1.0, 0.0])
    assert J[0, 0, LEG_CHAINS[0][3], 1] > J[0, 0, LEG_CHAINS[0][2], 1]  # the toes point along +y
    feet = [j for leg in LEG_CHAINS for j in leg[1:]]
    hips_z = J[0, 0, LEG_CHAINS[0][0], 2]
    J[0, :, [j for j in range(24) if j not in feet], 2] -= hips_z - 0.5
    for s, (hip, knee, ankle, toe) in enumerate(LEG_CHAINS):
        toe_off = J[0, :, toe] - J[0, :, ankle]
        J[0, :, knee] = J[0, :, hip] + lengths[knee] * fwd
        J[0, :, ankle] = J[0, :, knee] - [0.0, 0.0, lengths[ankle]]
        if s == 0:
            J[0, :, ankle, 1] += stagger
        J[0, :, toe] = J[0, :, ankle] + toe_off
    low = min(min(J[0, 0, a, 2] - 0.08, J[0, 0, t, 2] - 0.04) for _, _, a, t in LEG_CHAINS)
    J[0, :, :, 2] -= low
    return J


def test_a_seated_foot_the_network_moves_is_set_down_where_it_goes():
    """Sitting down keeps the stagger of the last step in the locks carried over from the context
    (17 cm in the demo; people sit with 2-5 cm). On the frames of a sit phase the feet carry little
    weight: when the network moves a foot more than ``replant_distance`` from its lock, the foot is
    lifted and set down there. Elsewhere (an upright body, or no sit phase given) the lock holds."""
    k, T = 3, 40
    lengths = bone_lengths_of(standing_body(1)[0, 0])
    stagger = np.r_[np.full(10, 0.17), np.linspace(0.17, 0.0, 18), np.zeros(T - 28)]  # slides back 1 cm/frame
    J = _seated_body(T, lengths, stagger)
    ankle = LEG_CHAINS[0][2]
    assert foot_contacts(J, FPS)[0, k:, 0].all()  # the sliding foot counts as planted all along
    seated = np.ones((1, T), bool)
    out = clean_feet(J, lengths, FPS, fixed=k, seated=seated)
    held = clean_feet(J, lengths, FPS, fixed=k, seated=seated, config=FootCleanupConfig(replant_distance=0.0))
    np.testing.assert_array_equal(clean_feet(J, lengths, FPS, fixed=k), held)  # no sit phase given
    np.testing.assert_allclose(held[0, k:, ankle, :2], np.broadcast_to(J[0, k - 1, ankle, :2], (T - k, 2)), atol=1e-6)
    # set down beside the right foot (locked at the mean of a run that begins while the network still slides)
    np.testing.assert_allclose(out[0, -8:, ankle, :2], J[0, -8:, ankle, :2], atol=0.015)
    assert np.abs(np.diff(out[0, :, ankle, :2], axis=0)).max() < 0.05  # no jump: it steps over a few frames
    low = np.minimum(out[0, :, ankle, 2] - 0.08, out[0, :, LEG_CHAINS[0][3], 2] - 0.04)
    lift = FootCleanupConfig().replant_lift
    assert low.min() > -1e-6 and 0.8 * lift <= low.max() < lift + 0.02  # on or over the floor; lifted, a step
    moving = np.linalg.norm(np.diff(out[0, :, ankle, :2], axis=0), axis=-1) > 1e-3
    assert (low[1:][moving] > 0.03).mean() > 0.5  # it moves mostly in the air, not sliding on the floor
    solved = np.flatnonzero(np.abs(out[0, :, ankle] - J[0, :, ankle]).max(-1) > 1e-9)  # the rest keep their leg
    assert len(solved) > 10
    np.testing.assert_allclose(bone_lengths_of(out[0, solved])[:, LEG_CHAINS[0][1:3]], np.broadcast_to(
        lengths[list(LEG_CHAINS[0][1:3])], (len(solved), 2)), atol=1e-6)
    standing = standing_body(T)  # a slide of 8 cm (within the straight leg's reach) on an upright body: the lock holds
    standing[0][:, [ankle, LEG_CHAINS[0][3]], 1] += 0.5 * stagger[:, None]
    kept = clean_feet(standing, lengths, FPS, fixed=k)
    # (within the straight leg's IK clamp, < 1 mm; the network's foot went 8.5 cm)
    np.testing.assert_allclose(kept[0, k:, ankle, :2], np.broadcast_to(standing[0, k - 1, ankle, :2], (T - k, 2)), atol=1e-3)
    with pytest.raises(ValueError, match="replant_distance"):
        FootCleanupConfig(replant_distance=-0.1)
