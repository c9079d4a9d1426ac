"""When the hands let go of a carried (free) object (iReplica §4.3, extended).

iReplica releases an object when the contact network predicts the end of the contact (§4.3,
Fig. 4 D). On real motion the network fires on the reach down that picks an object up and on the
one that puts it down, and often not on the carry between them: the contact ends while the hands
still hold the object up, which the paper's release would leave hanging in the air (issue 36.6:
a box left 92 cm from the hands, a bottle 2.2 m up). A carried object can only be let go where it
rests on something, so (not in the paper):

- ``carried_release``: the object rides on the holding hand from its attach frame. If it is not
  within ``REST_M`` of a surface at the detach frame, or its bottom rises more than ``LIFT_M``
  after the detach frame and before the predicted contact ends, or (when the
  contact moved it less than ``CARRY_M``: a contact on the reach that picks it up only) more than
  ``PICK_LIFT_M`` within ``PICK_S`` after the contact's end, the hands carry it: the contact is not
  over. It is held on until it touches down after its highest frame (``touchdown``: within
  ``REST_M`` of a surface, or stopping to come down within ``LIFT_M`` of one, moving at most
  ``STILL_MPS``), or to the end of the motion when it never does (carried to the end). Otherwise
  the object rests where the hand let go and the detach frame stands.
- an object attached while the hand is still coming down would be pushed into its support by the
  riding: it is taken at its deepest frame instead (``lift_off``), the hand's lowest reach.
- at the release the object settles upright on the surface under it (``SupportQuery.rest_pose``,
  applied by ``interactions.drive_contact``): no object floats after a put-down.
"""
from __future__ import annotations

import numpy as np

from trumans.track.support import SupportQuery

__all__ = ["LIFT_M", "REST_M", "CARRY_M", "STILL_MPS", "PICK_LIFT_M", "PICK_S", "lift_off", "touchdown", "carried_release"]

LIFT_M = 0.10  # m, an object whose bottom rises this far while the contact lasts is being carried
REST_M = 0.03  # m, an object whose bottom comes this close to the surface under it can be let go there
CARRY_M = 0.15  # m, a contact that moved its object this far carried it (its end is the put-down)
STILL_MPS = 0.3  # m/s, an object set down moves at most this fast (horizontally) when it touches down
PICK_LIFT_M = 0.30  # m, after a contact on the reach only, the hand lifts a picked-up object this far ...
PICK_S = 1.5  # s ... within this long after the contact's end (a hand leaving a table rises less)


def lift_off(gaps: np.ndarray, last: int, rest: float = REST_M) -> int:
    """Index of the frame a free object really leaves the hand's approach: riding on the hand from
    index 0, it would sink more than ``rest`` into the surface under it while the hand still comes
    down, so it is taken at its deepest frame up to ``last`` (the hand's lowest reach); 0 when it
    never sinks that far. gaps: (n,) m (``SupportQuery.gaps``)."""
    g = np.asarray(gaps, np.float64)[: last + 1]
    return int(np.argmin(g)) if g.min() < -rest else 0


def touchdown(gaps: np.ndarray, start: int, speed: np.ndarray | None = None, rest: float = REST_M,
              lift: float = LIFT_M, still: float = STILL_MPS) -> int | None:
    """Index of the first frame from ``start`` on where a carried object's bottom comes within ``rest``
    of the surface under it or stops coming down within ``lift`` of it (a local minimum: the hands
    set it down onto a surface a few cm off its tracked height), moving at most ``still`` m/s
    (``speed`` (n,), None: not checked; an object carried past a table at walking pace is not set
    down on it); None if there is none. A frame needs its successor to count as a local minimum.
    gaps: (n,) m (``SupportQuery.gaps``)."""
    g = np.asarray(gaps, np.float64)[start:]
    low = np.zeros(len(g), bool)
    low[1:-1] = (g[1:-1] <= lift) & (g[1:-1] <= g[:-2]) & (g[1:-1] < g[2:])
    ok = (g <= rest) | low
    if speed is not None:
        ok &= np.asarray(speed, np.float64)[start:start + len(g)] <= still
    hit = np.flatnonzero(ok)
    return start + int(hit[0]) if len(hit) else None


def carried_release(support: SupportQuery, name: str, ride: np.ndarray, attach: int, detach: int, contact_end: int,
                    others: dict[str, np.ndarray], fps: float, lift: float = LIFT_M, rest: float = REST_M,
                    carry: float = CARRY_M, pick_lift: float = PICK_LIFT_M, pick_s: float = PICK_S) -> int:
    """The frame (exclusive end of the hold) at which free object ``name`` is let go (module doc).
    ride: (n, 4, 4) its poses riding on the hand from frame ``attach`` to the end of the motion
    (``interactions.drive_object``: on the holding wrist, or between two hands); detach: the detach frame found on the hands' speed (``attach_detach``);
    contact_end: the predicted contact's end (>= detach); others: the other objects' poses
    {name: (4, 4)} (supports); fps: frames per second. Returns ``detach`` when the object rests
    there and is not carried up (module doc), else the frame after it touches down past its
    highest frame (``touchdown``), else ``attach + n`` (held to the end)."""
    n = len(ride)
    if not attach < detach <= contact_end <= attach + n:
        raise ValueError(f"need attach < detach <= contact_end <= attach + len(ride), got {attach}, {detach}, "
                         f"{contact_end}, {attach + n}")
    gaps = _LazyGaps(support, name, ride, others)
    d, ce = detach - 1 - attach, contact_end - attach  # d: the last held frame
    centre = ride[:, :3, 3]
    speed = np.linalg.norm(np.gradient(centre[:, :2], axis=0), axis=-1) * fps if n > 1 else np.zeros(n)  # (n,) m/s
    moved = float(np.linalg.norm(centre[: d + 1] - centre[0], axis=-1).max())
    vertices = np.asarray(support.scene.objects[name].mesh.vertices, np.float64)
    stop = min(n, max(ce, d + 1) + (int(round(pick_s * fps)) if moved <= carry else 0))
    bottom = (np.einsum("nj,vj->nv", ride[d:stop, 2, :3], vertices) + ride[d:stop, 2, 3:4]).min(1)  # (m,) m
    rise = bottom - bottom[0]  # the object's own rise from the last held frame (not its gap: it may pass a table edge)
    inside = rise[: max(ce, d + 1) - d]  # to the contact's end
    carried = inside.max() > lift or gaps.upto(d + 1)[d] > rest
    if not carried and moved <= carry:  # a contact on the reach only: does the hand take it up right after?
        carried = rise.max() > pick_lift
    window = rise if moved <= carry else inside
    if not carried:
        return detach  # let go where it rests: a put-down, or a touch that did not take it
    peak = d + int(np.argmax(window))  # carried up: it comes down after its highest frame (of the contact)
    while True:  # a few seconds at a time: the touchdown is usually near
        g = gaps.upto(gaps.done + _CHUNK)
        k = touchdown(g, peak, speed, rest, lift)
        if gaps.done >= n or (k is not None and k + 1 < gaps.done):
            break  # found (a local minimum needs the frame after it), or the end of the motion
    return attach + k + 1 if k is not None else attach + n


_CHUNK = 90  # frames of gaps computed at a time while looking for the touchdown
_STRIDE = 3  # frames between the gaps computed


class _LazyGaps:
    """``SupportQuery.gaps`` of one ride (n, 4, 4), computed on the leading frames only as far as asked,
    on every ``_STRIDE``-th frame and the last one asked for, linearly in between (a carried object's
    height above the surfaces changes smoothly at 30 fps; the ray casts are the tracker's costliest step)."""

    def __init__(self, support: SupportQuery, name: str, ride: np.ndarray, others: dict[str, np.ndarray]) -> None:
        self.support, self.name, self.ride, self.others = support, name, ride, others
        self.values = np.zeros(0)

    @property
    def done(self) -> int:
        return len(self.values)

    def upto(self, stop: int) -> np.ndarray:
        """The gaps of frames [0, min(stop, n))."""
        stop = min(stop, len(self.ride))
        if stop > self.done:
            frames = np.unique(np.r_[np.arange(self.done, stop, _STRIDE), stop - 1])
            got = self.support.gaps(self.name, self.ride[frames], self.others)
            if self.done:  # the last computed frame joins the new samples
                frames, got = np.r_[self.done - 1, frames], np.r_[self.values[-1], got]
            self.values = np.r_[self.values, np.interp(np.arange(self.done, stop), frames, got)]
        return self.values[:stop]
