"""Binary-classification figures for per-frame contact predictions (iReplica Tab. 3).

``average_precision``: area under the precision-recall curve as the step sum
``sum_n (R_n - R_{n-1}) P_n`` over thresholds at each distinct score (scikit-learn's definition).
"""
from __future__ import annotations

import numpy as np

__all__ = ["average_precision", "binary_scores"]


def _check(scores: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    s = np.asarray(scores, dtype=np.float64).ravel()
    y = np.asarray(labels).ravel()
    if s.shape != y.shape:
        raise ValueError(f"scores and labels must have the same size, got {np.shape(scores)} and {np.shape(labels)}")
    if y.dtype != bool:
        raise ValueError(f"labels must be boolean, got dtype {y.dtype}")
    if not np.isfinite(s).all():
        raise ValueError("scores contain NaN or inf")
    return s, y


def average_precision(scores: np.ndarray, labels: np.ndarray) -> float:
    """AP of ``scores`` (any shape) against boolean ``labels`` (same shape); NaN without positives."""
    s, y = _check(scores, labels)
    if not y.any():
        return float("nan")
    order = np.argsort(-s, kind="mergesort")
    s, y = s[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s) != 0), len(s) - 1]  # last index of each distinct score
    tp = np.cumsum(y)[last]
    precision = tp / (last + 1)
    recall = tp / y.sum()
    return float(np.sum(np.diff(np.r_[0.0, recall]) * precision))


def binary_scores(scores: np.ndarray, labels: np.ndarray, threshold: float = 0.5) -> dict[str, float]:
    """{ap, precision, recall, accuracy} of probabilities ``scores`` at ``threshold``."""
    s, y = _check(scores, labels)
    pred = s >= threshold
    tp = float((pred & y).sum())
    return {
        "ap": average_precision(s, y),
        "precision": tp / max(float(pred.sum()), 1.0),
        "recall": tp / max(float(y.sum()), 1.0),
        "accuracy": float((pred == y).mean()) if len(y) else float("nan"),
    }
