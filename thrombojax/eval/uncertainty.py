"""How well an ensemble's spread predicts the error of its mean (host-side numpy).

Inputs are an ensemble rollout (:mod:`thrombojax.simulator.ensemble`): the member mean
``[n_steps, N, 3]``, the per-node spread ``[n_steps, N]`` and the truth ``[n_steps, N, 3]``; only
real clot nodes count. Definitions (per step, over the clot nodes):

- **error** of a node: ``|mean - truth| / sqrt(3)``, the root-mean-square over x, y, z of the
  error of the mean, the same per-axis RMS convention as the spread (``sqrt(trace(cov) / 3)``),
  so a calibrated Gaussian ensemble has error ~ spread.
- **spearman**: Spearman rank correlation between per-node spread and per-node error (does the
  spread rank the nodes by their error; ties get average ranks). **pearson**: the same with the
  Pearson (linear) correlation. NaN when either is constant over the nodes (e.g. a zero spread).
- **calibration**: mean error / mean spread (1: spread as large as the error on average; > 1:
  over-confident, < 1: under-confident). **rms_calibration**: RMS error / RMS spread, which is 1
  in expectation for a calibrated Gaussian ensemble of many members.
- **within_2_spread**: fraction of clot nodes whose error is at most 2 spreads (a calibrated
  Gaussian ensemble gives P(chi2_3 <= 12) = 0.993).

Errors and spreads are in the inputs' length unit times ``scale`` (pass the run's length per
scaled unit to report vessel radii); correlations, ratios and fractions do not depend on it.
"""

from __future__ import annotations

import math

import numpy as np

from thrombojax.errors import DatasetError
from thrombojax.types import clot_mask

__all__ = [
    "CURVE_KEYS",
    "node_errors",
    "pearson",
    "spearman",
    "uncertainty_curves",
    "uncertainty_summary",
    "uncertainty_report",
]

CURVE_KEYS: tuple[str, ...] = (
    "error", "spread", "spearman", "pearson", "calibration", "rms_calibration",
    "within_2_spread",
)  # fmt: skip


def node_errors(mean: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Per-node RMS-over-axes error of the ensemble mean.

    Args:
        mean, truth: ``[..., N, 3]`` positions.
    Returns:
        ``[..., N]`` float64 ``|mean - truth| / sqrt(3)``.
    """
    mean, truth = np.asarray(mean, np.float64), np.asarray(truth, np.float64)
    if mean.shape != truth.shape or mean.shape[-1:] != (3,):
        raise DatasetError(f"uncertainty: mean {mean.shape} and truth {truth.shape} must both be "
                           "[..., N, 3]")
    return np.sqrt(np.mean((mean - truth) ** 2, axis=-1))


def pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two ``[n]`` arrays; NaN when n < 2 or either is constant."""
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if a.size < 2:
        return math.nan
    da, db = a - a.mean(), b - b.mean()
    den = math.sqrt(float(da @ da) * float(db @ db))
    if den == 0.0 or not math.isfinite(den):
        return math.nan
    return float(np.clip(float(da @ db) / den, -1.0, 1.0))


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman rank correlation (average ranks for ties) of two ``[n]`` arrays; NaN when n < 2
    or either is constant."""
    a, b = np.asarray(a, np.float64).ravel(), np.asarray(b, np.float64).ravel()
    if a.size < 2:
        return math.nan
    from scipy.stats import rankdata  # here: scipy.stats adds ~0.4 s to every command's start

    return pearson(rankdata(a), rankdata(b))


def _prepare(mean, spread, truth, node_type, mask):
    err = node_errors(mean, truth)
    spread = np.asarray(spread, np.float64)
    if spread.shape != err.shape or err.ndim != 2:
        raise DatasetError(f"uncertainty: spread {spread.shape} must be [n_steps, N] matching "
                           f"mean {np.shape(mean)}")
    sel = np.asarray(clot_mask(np.asarray(node_type), None if mask is None else
                               np.asarray(mask, bool)), bool)
    if sel.shape != (err.shape[1],):
        raise DatasetError(f"uncertainty: node_type {np.shape(node_type)} does not fit "
                           f"{err.shape[1]} nodes")
    if not sel.any():
        raise DatasetError("uncertainty: no real clot nodes to measure")
    return err[:, sel], spread[:, sel]


def _ratio(num: float, den: float) -> float:
    return num / den if den > 0 else (math.nan if num == 0 else math.inf)


def uncertainty_curves(
    mean: np.ndarray,
    spread: np.ndarray,
    truth: np.ndarray,
    node_type: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    scale: float = 1.0,
) -> dict[str, np.ndarray]:
    """Spread-versus-error measures per step (module docstring for the definitions).

    Args:
        mean: ``[n_steps, N, 3]`` ensemble mean. spread: ``[n_steps, N]`` per-node spread.
        truth: ``[n_steps, N, 3]`` true positions of the same frames.
        node_type: ``[N]`` NodeType values. mask: optional ``[N]`` real-node mask.
        scale: length unit of the ``error`` and ``spread`` curves per input unit.
    Returns:
        :data:`CURVE_KEYS` -> ``[n_steps]`` float64: mean clot-node ``error`` and ``spread``
        (times ``scale``), ``spearman``, ``pearson``, ``calibration``, ``rms_calibration``,
        ``within_2_spread``.
    """
    err, spr = _prepare(mean, spread, truth, node_type, mask)
    curves = {
        "error": err.mean(axis=1) * scale,
        "spread": spr.mean(axis=1) * scale,
        "spearman": np.array([spearman(s, e) for s, e in zip(spr, err, strict=True)]),
        "pearson": np.array([pearson(s, e) for s, e in zip(spr, err, strict=True)]),
        "calibration": np.array([_ratio(e.mean(), s.mean()) for s, e in zip(spr, err,
                                                                             strict=True)]),
        "rms_calibration": np.array([_ratio(math.sqrt(np.mean(e**2)), math.sqrt(np.mean(s**2)))
                                     for s, e in zip(spr, err, strict=True)]),
        "within_2_spread": (err <= 2.0 * spr).mean(axis=1),
    }
    return {k: np.asarray(curves[k], np.float64) for k in CURVE_KEYS}


def _json_float(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def uncertainty_summary(
    mean: np.ndarray,
    spread: np.ndarray,
    truth: np.ndarray,
    node_type: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    scale: float = 1.0,
) -> dict:
    """JSON-ready summary of how well spread predicts error, pooled over steps and clot nodes.

    Args:
        as :func:`uncertainty_curves`.
    Returns:
        A dict of floats (``None`` where undefined): ``spearman`` and ``pearson`` pooled over
        every (step, node) pair; ``spearman_per_step_mean`` (mean of the per-step values);
        ``temporal_pearson`` (Pearson over steps of the mean spread and mean error curves:
        does the spread grow as the error grows); ``calibration``, ``rms_calibration``,
        ``within_2_spread`` pooled; ``final_*`` the same at the last step; ``mean_error``,
        ``mean_spread`` (times ``scale``); ``n_steps``, ``n_clot_nodes``; and the definitions
        (``correlation``, ``spread_definition``, ``error_definition``).
    """
    err, spr = _prepare(mean, spread, truth, node_type, mask)
    curves = uncertainty_curves(mean, spread, truth, node_type, mask, scale=scale)
    per_step = curves["spearman"][np.isfinite(curves["spearman"])]
    out = {
        "spearman": spearman(spr, err),
        "pearson": pearson(spr, err),
        "spearman_per_step_mean": float(per_step.mean()) if per_step.size else math.nan,
        "temporal_pearson": pearson(curves["spread"], curves["error"]),
        "calibration": _ratio(err.mean(), spr.mean()),
        "rms_calibration": _ratio(math.sqrt(np.mean(err**2)), math.sqrt(np.mean(spr**2))),
        "within_2_spread": float((err <= 2.0 * spr).mean()),
        "final_spearman": curves["spearman"][-1],
        "final_calibration": curves["calibration"][-1],
        "final_within_2_spread": curves["within_2_spread"][-1],
        "mean_error": float(err.mean()) * scale,
        "mean_spread": float(spr.mean()) * scale,
    }
    summary: dict = {k: _json_float(v) for k, v in out.items()}
    summary.update(
        n_steps=int(err.shape[0]), n_clot_nodes=int(err.shape[1]),
        correlation="spearman (rank) and pearson (linear), spread vs error of the mean per node",
        spread_definition="sqrt(trace(member covariance) / 3), population covariance",
        error_definition="|mean - truth| / sqrt(3) (RMS over x, y, z)",
    )
    return summary


def uncertainty_report(
    mean: np.ndarray,
    spread: np.ndarray,
    truth: np.ndarray,
    node_type: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    scale: float = 1.0,
) -> tuple[dict[str, np.ndarray], dict]:
    """Both :func:`uncertainty_curves` (``[n_steps]`` arrays) and :func:`uncertainty_summary`
    (JSON-ready), for the ``rollout`` command's output. Arguments as there."""
    return (uncertainty_curves(mean, spread, truth, node_type, mask, scale=scale),
            uncertainty_summary(mean, spread, truth, node_type, mask, scale=scale))
