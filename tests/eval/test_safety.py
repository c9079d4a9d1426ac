"""Scene-safety metrics (trumans.eval.safety) on analytic cases: a thin wall, a closed room."""
import numpy as np
import pytest
from helpers import standing_body

from trumans.eval.safety import (core_depths, crossings, feet_off_frames, floating_frames, lying_leg_depths,
                                 room_exits, seat_errors, sinking_frames, swept_dips)
from trumans.scenes.occupancy import OccupancyGrid
from trumans.scenes.sdf import SceneSDF, outside_columns
from trumans.skeleton import JOINT_INDEX

WRIST = JOINT_INDEX["right_wrist"]


def _grid(solid) -> OccupancyGrid:
    """2 cm voxels over x, y in [0, 3.2], z in [-0.09, 2.3]; floor below z = 0 plus ``solid(x, y, z)``."""
    origin = np.array([0.01, 0.01, -0.09])
    n = (160, 160, 120)
    x, y, z = np.meshgrid(*(origin[i] + 0.02 * np.arange(n[i]) for i in range(3)), indexing="ij")
    return OccupancyGrid((z < 0) | solid(x, y, z), origin, 0.02)


def thin_wall() -> SceneSDF:
    """A 12 cm wall x in [1.5, 1.62] across the whole grid (an open scene: both sides reach the border)."""
    return SceneSDF(_grid(lambda x, y, z: (x > 1.5) & (x < 1.62)))


def closed_room() -> SceneSDF:
    """Interior x, y in [0.4, 2.8], 12 cm walls outside it, 2.5 m high; free space around the walls."""
    def solid(x, y, z):
        inner = (x > 0.4) & (x < 2.8) & (y > 0.4) & (y < 2.8)
        outer = (x > 0.28) & (x < 2.92) & (y > 0.28) & (y < 2.92)
        return outer & ~inner & (z < 2.5)
    return SceneSDF(_grid(solid))


def _body_at(T: int, xy: np.ndarray) -> np.ndarray:
    """(T, 24, 3) standing bodies with the pelvis at xy (T, 2)."""
    J = standing_body(T)[0].copy()
    J[..., :2] += (np.asarray(xy) - J[:, JOINT_INDEX["pelvis"], :2])[:, None]
    return J


def test_a_body_that_jumps_through_a_thin_wall_between_two_frames_is_caught():
    sdf = thin_wall()
    T = 6
    x = np.r_[1.0, 1.1, 1.2, 1.95, 2.05, 2.15]  # frame 2 -> 3: the whole body passes the wall
    J = _body_at(T, np.c_[x, np.full(T, 1.6)])
    assert core_depths(J, sdf).max() == 0.0  # no frame is inside anything: penetration alone misses it
    cross = crossings(J, sdf)
    assert cross[3].all() and not cross[[0, 1, 2, 4, 5]].any()
    assert swept_dips(J, sdf)[3].min() > 0.04  # every joint dips ~6 cm, into the 12 cm wall's middle


def test_a_body_walking_along_the_wall_does_not_cross():
    sdf = thin_wall()
    T = 20
    J = _body_at(T, np.c_[np.full(T, 1.25), np.linspace(0.5, 2.5, T)])  # 25 cm from the wall, along it
    assert not crossings(J, sdf).any()
    # a hand swept along inside the wall's face (both ends 2 cm in) does not cross either
    J[:, WRIST] = np.c_[np.full(T, 1.52), np.linspace(0.5, 2.5, T), np.full(T, 1.0)]
    assert not crossings(J, sdf).any()
    # ... but one that goes from one face to the other in a frame does
    J[10, WRIST, 0] = 1.7
    J[9, WRIST, 0] = 1.42
    assert crossings(J, sdf)[10, WRIST]


def test_the_outside_of_a_closed_room_is_solid_and_an_exit():
    sdf = closed_room()
    enc = sdf.enclosed()
    assert enc.outside is not None and enc.outside.any()
    inside, beyond, far = np.array([1.6, 1.6]), np.array([1.6, 0.1]), np.array([1.6, -0.3])
    assert not room_exits(inside[None], sdf)[0]
    assert room_exits(np.stack([beyond, far]), sdf).all()  # past the wall, and beyond the grid
    J = _body_at(2, np.stack([inside, beyond]))
    d = core_depths(J, sdf)
    assert d[0].max() == 0.0
    assert d[1, JOINT_INDEX["pelvis"]] > 0.09 + 0.15  # as deep as it is far from the room (0.3 m): not free space
    assert not outside_columns(thin_wall().grid()).any()  # an open scene has no outside
    assert thin_wall().enclosed().outside is None


def test_feet_seat_and_lying_figures():
    T = 4
    J = _body_at(T, np.zeros((T, 2)))
    up = np.ones(T, bool)
    assert not floating_frames(J, up).any() and not sinking_frames(J).any() and not feet_off_frames(J, up).any()
    J[1, :, 2] += 0.2  # the whole body in the air
    J[2, :, 2] -= 0.05  # feet under the floor
    assert floating_frames(J, up).tolist() == [False, True, False, False]
    assert feet_off_frames(J, up).tolist() == [False, True, False, False]
    assert not floating_frames(J, np.zeros(T, bool)).any()  # seated frames do not float
    assert sinking_frames(J).tolist() == [False, False, True, False]
    seat = np.array([np.nan, 0.5, 0.45, np.nan])
    err = seat_errors(J, seat, offset=0.0)
    pelvis = J[[1, 2], JOINT_INDEX["pelvis"], 2]
    np.testing.assert_allclose(err, np.abs(pelvis - seat[1:3]))
    over = np.ones((T, 8), bool)
    surface = np.array([np.nan, np.nan, np.nan, 10.0])  # a surface far above every leg joint
    assert lying_leg_depths(J, surface, over).min() > 9.0 and len(lying_leg_depths(J, surface, over)) == 8
    assert len(lying_leg_depths(J, surface, np.zeros((T, 8), bool))) == 0
    with pytest.raises(ValueError, match="joints must be"):
        crossings(np.zeros((3, 23, 3)), thin_wall())
    with pytest.raises(ValueError, match="upright"):
        floating_frames(J, np.ones(T + 1, bool))


def test_a_body_creeping_through_a_wall_over_several_frames_crosses_and_one_dipping_in_does_not():
    sdf = thin_wall()
    T = 10
    x = np.r_[1.3, 1.4, 1.48, 1.52, 1.56, 1.6, 1.64, 1.72, 1.8, 1.9]  # 4 cm a frame: never a dip of a segment
    J = _body_at(T, np.c_[x, np.full(T, 1.6)])
    assert not (swept_dips(J, sdf) > 0.01).any()
    assert crossings(J, sdf)[:, JOINT_INDEX["pelvis"]].any()
    back = np.r_[1.3, 1.35, 1.38, 1.4, 1.42, 1.42, 1.4, 1.38, 1.35, 1.3]  # the toes in and out on one side
    J = _body_at(T, np.c_[back, np.full(T, 1.6)])
    assert core_depths(J, sdf).max() > 0.02 and not crossings(J, sdf).any()
