"""Where a rollout's clot goes wrong: its centroid error split along and across the true
clot's track, and its size against the true clot's.

The final centroid error alone cannot tell a clot that is too slow (it lags along the true
track) from one that takes another path (it is off the track) or one that stretches or
compresses differently (its centroid moves with its shape). The true centroids of the frames
form a polyline, the *track*. Each predicted centroid is projected onto it: the arc length
between the projection and the true centroid of the same frame is the error **along** the
track (> 0: ahead of the true clot), the distance to the track the error **across** it. The
first and last segments are extended beyond the track's ends, so a clot that lags behind the
start or runs past the last true frame is measured too. The projection is onto the nearest
segment; a track that folds back to within the error of itself may pick the wrong fold.

Pure NumPy, after the rollout (``experiments/ladder_eval.py`` records all three per step).
"""

from __future__ import annotations

import numpy as np

from thrombojax.eval.metrics import clot_centroids

__all__ = ["track_errors", "size_ratio"]


def _centroids(frames: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    if not np.asarray(clot_mask, bool).any():
        raise ValueError("track: the clot mask selects no node")
    return clot_centroids(frames, clot_mask)


def track_errors(pred: np.ndarray, true: np.ndarray, clot_mask: np.ndarray,
                 start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The centroid error along and across the true clot's track, per frame.

    Args:
        pred, true: ``[T, n_nodes, 3]`` predicted and true frames (the same frames).
        clot_mask: ``[n_nodes]`` bool, the clot nodes.
        start: optional ``[n_nodes, 3]`` frame the rollout started from; it begins the track,
            so that the first steps have a segment behind them.

    Returns:
        ``(along, across)``, each ``[T]`` in the units of the positions: the signed arc length
        from the true centroid of the frame to the predicted centroid's projection on the track
        (> 0 ahead), and the predicted centroid's distance from the track.
    """
    pred, true = np.asarray(pred), np.asarray(true)
    if pred.shape != true.shape or pred.ndim != 3:
        raise ValueError(f"track: pred {pred.shape} and true {true.shape} must be the same "
                         "[T, n_nodes, 3]")
    track = _centroids(true if start is None else np.concatenate([start[None], true]),
                       clot_mask)
    offset = 0 if start is None else 1
    if len(track) < 2:
        raise ValueError("track: the true track needs at least two frames")
    a, b = track[:-1], track[1:]
    seg = b - a
    length = np.linalg.norm(seg, axis=-1)
    s0 = np.concatenate([[0.0], np.cumsum(length)])  # arc length at each track point
    c = _centroids(pred, clot_mask)
    # projection parameter of every predicted centroid on every segment: [T, n_seg]
    denom = np.maximum(length**2, 1e-300)
    u = np.einsum("tsk,sk->ts", c[:, None] - a[None], seg) / denom
    lo = np.zeros(len(seg))
    hi = np.ones(len(seg))
    lo[0], hi[-1] = -np.inf, np.inf  # the end segments extend beyond the track's ends
    u = np.where(length > 0, np.clip(u, lo, hi), 0.0)
    foot = a[None] + u[..., None] * seg[None]
    dist = np.linalg.norm(c[:, None] - foot, axis=-1)
    k = dist.argmin(axis=1)
    rows = np.arange(len(c))
    s_pred = s0[k] + u[rows, k] * length[k]
    along = s_pred - s0[offset:offset + len(c)]
    return along, dist[rows, k]


def size_ratio(pred: np.ndarray, true: np.ndarray, clot_mask: np.ndarray) -> np.ndarray:
    """The predicted clot's radius of gyration over the true clot's, per frame ``[T]``
    (1: the same size; > 1: stretched or swollen)."""
    sel = np.asarray(clot_mask, bool)

    def gyration(frames: np.ndarray) -> np.ndarray:
        x = np.asarray(frames, np.float64)[:, sel]
        return np.sqrt(((x - x.mean(axis=1, keepdims=True)) ** 2).sum(-1).mean(axis=1))

    return gyration(pred) / np.maximum(gyration(true), 1e-300)
