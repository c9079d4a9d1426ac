"""`trumans eval contacts --real`: clip choice, pooling and the flag's errors (issue 36.6)."""
from __future__ import annotations

import numpy as np
import pytest

from trumans.track.eval_real import FLOAT_TOL_M, handling_clips, pool


def _row(inter: int, union: int, gt: int, floats: list[float], fps: float = 30.0, frames: int = 60) -> dict:
    prob = np.linspace(0, 1, frames * 2).reshape(frames, 2)
    labels = prob > 0.5
    return {"clip": "x", "frames": frames, "fps": fps, "fitted": [], "prob": prob, "labels": labels, "grasp": labels,
            "held_inter": inter, "held_union": union, "gt_held_frames": gt, "tracker_held_frames": union,
            "false_hold_frames": 30, "out_of_reach_frames": 15, "contact_nothing_frames": 3, "raw_nothing_frames": 6,
            "centre_err": [np.array([1.0, 3.0])], "end_err": [3.0], "hand_d": [np.array([2.0])], "floats": floats,
            "interactions": []}


def test_pool_sums_frames_before_dividing():
    fig = pool([_row(10, 20, 10, [0.0]), _row(30, 40, 40, [5.0, 1.0])])
    assert fig["held_iou"] == pytest.approx(40 / 60) and fig["held_share"] == pytest.approx(40 / 50)
    assert fig["ap"] == pytest.approx(1.0) and fig["held_ap"] == pytest.approx(1.0)
    assert fig["obj_center_err_cm"] == pytest.approx(2.0) and fig["hand_obj_dist_cm"] == pytest.approx(2.0)
    assert fig["float_max_cm"] == 5.0 and fig["releases"] == 3
    assert fig["floating"] == sum(f > 100 * FLOAT_TOL_M for f in (0.0, 5.0, 1.0)) == 1
    assert fig["false_hold_s"] == pytest.approx(2.0) and fig["out_of_reach_s"] == pytest.approx(1.0)
    assert fig["contact_nothing_s"] == pytest.approx(0.2) and fig["contact_nothing_s_raw"] == pytest.approx(0.4)
    assert fig["motion_min"] == pytest.approx(4 / 60)


def test_handling_clips_are_the_held_out_pick_ups_first():
    clips = handling_clips("test")
    names = [c.name for c in clips]
    assert {c.split for c in clips} == {"test"}
    assert names[:3] == ["111_17", "111_18", "111_36"]  # described as picking up / carrying
    assert "86_15" in names  # a palm reaches down (no object fitted: nothing should be held)


def test_real_and_data_together_are_refused():
    from trumans.track.evaluate import main

    with pytest.raises(ValueError, match="--real or --data"):
        main(["--real", "--data", "somewhere"])
