"""Faster forms in the HOI filter's post-steps against the straightforward ones they replaced (issue 38)."""
import warnings

import numpy as np

from trumans.refine.bones import project_bone_lengths
from trumans.refine.tracked import column_median
from trumans.skeleton import DEPTH, NUM_JOINTS, PARENTS

_ORDER = np.argsort(DEPTH[1:], kind="stable") + 1  # the projection's bone order: parents before children


def _project_one_by_one(joints: np.ndarray, lengths: np.ndarray, rounds: int = 8) -> np.ndarray:
    """The earlier project_bone_lengths: every bone moved on its own, in _ORDER."""
    X = np.ascontiguousarray(joints.transpose(1, 0, 2))
    for _ in range(rounds):
        for j in _ORDER:
            if not np.isfinite(lengths[j]):
                continue
            p = PARENTS[j]
            d = X[j] - X[p]
            n = np.sqrt(np.einsum("ti,ti->t", d, d))[:, None]
            half = 0.5 * np.where(n > 1e-9, 1.0 - lengths[j] / np.maximum(n, 1e-9), 0.0) * d
            X[p] += half
            X[j] -= half
    out = X.copy()
    for j in _ORDER:
        p = PARENTS[j]
        v = X[j] - X[p]
        if np.isfinite(lengths[j]):
            n = np.sqrt(np.einsum("ti,ti->t", v, v))[:, None]
            v = np.where(n > 1e-9, v * (lengths[j] / np.maximum(n, 1e-9)), v)
        out[j] = out[p] + v
    return out.transpose(1, 0, 2).copy()


def test_grouped_bone_projection_is_the_one_by_one_sequence():
    rng = np.random.default_rng(0)
    J = rng.normal(0, 0.3, (200, NUM_JOINTS, 3))
    J[5, 4] = J[5, 1]  # a zero-length bone
    L = rng.uniform(0.05, 0.5, NUM_JOINTS)
    L[0] = 0.0
    L[[7, 13]] = np.nan  # bones kept as they are
    got = project_bone_lengths(J, L)
    want = _project_one_by_one(J, L)
    assert np.abs(got - want).max() < 1e-12
    b = np.linalg.norm(got[:, 1:] - got[:, PARENTS[1:]], axis=-1)
    ok = np.isfinite(L[1:])
    assert np.abs(b[:, ok] - L[1:][ok]).max() < 1e-9


def test_column_median_is_nanmedian():
    rng = np.random.default_rng(1)
    for T in (1, 2, 7, 300):
        v = rng.exponential(size=(T, NUM_JOINTS))
        seen = rng.random((T, NUM_JOINTS)) > 0.4
        seen[:, 0], seen[:, 1] = False, True
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want = np.nanmedian(np.where(seen, v, np.nan), axis=0)
        got = column_median(v, seen)
        assert np.array_equal(np.isnan(got), np.isnan(want))
        assert np.array_equal(got[np.isfinite(got)], want[np.isfinite(want)])
