"""The factor on a model's learned steps (the guards' ``pace``) fitted on validation simulations.

The hypothesis it tests: on ClotEntry a model's clot runs along the vessel a little too fast or
too slow, by an amount set by its seed; if that amount were shared by the vessels it is rolled
out on, one factor on every learned step, fitted where the truth is known, would take it out
for one rung's few ensemble members as averaging many members does. The guards' ``pace``
(:meth:`thrombojax.simulator.guard_set.GuardSet.pace_step`) multiplies every clot node's
learned step; this module picks it so that the rolled-out clot ends where the true clot does
along the true track (:func:`thrombojax.eval.track.track_errors`), on simulations the model
was not trained on and is not then measured on (a run's validation split). Measured, it does
not carry over. The lag builds up in particular stretches of each vessel, not at a uniform
rate, so a pace fitted on one vessel makes the others worse. And where the model carries its
own speed (past a vessel's open end), a pace above 1 compounds at every step: one measured
clot diverged (``experiments/results/ladder_budget/clotentry_pace/README.md``). It is
therefore no option of ``thrombojax rollout``; it stays here, with that measurement, as a tool
to ask the question of other models and datasets.

:func:`fit_pace` is the search, pure: it is given the final signed along-track error (vessel
radii, > 0 ahead) as a function of the pace and the true track's length. From ``pace = 1`` the
first guess scales the step by the ratio of the true clot's path to the model's; then secant
steps, within ``bounds``, until the error is within ``tol_r`` or ``max_evals`` rollouts are
spent. The pace with the smallest error measured is returned with every evaluation.
:func:`fit_pace_on_simulations` supplies that function: guarded rollouts of the model (or
ensemble) on the given simulations, their final along-track errors averaged.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.eval.drift import centroid_speed
from thrombojax.eval.rollouts import rollout_simulation
from thrombojax.eval.track import track_errors
from thrombojax.types import clot_mask

__all__ = ["fit_pace", "fit_pace_on_simulations", "PACE_BOUNDS"]

PACE_BOUNDS: tuple[float, float] = (0.5, 2.0)
"""The paces :func:`fit_pace` may choose: a model more than twice too fast or slow is wrong
in more than its pace."""


def fit_pace(along_at: Callable[[float], float], track_length_r: float, *, tol_r: float = 0.05,
             max_evals: int = 5, bounds: tuple[float, float] = PACE_BOUNDS) -> dict:
    """The pace at which ``along_at`` (final signed along-track error, radii) is nearest 0.

    Args:
        along_at: ``pace -> final along-track error`` in vessel radii (> 0: ahead).
        track_length_r: how far the true clot travels along its track (radii, > 0).
        tol_r: stop when ``|error| <= tol_r``.
        max_evals: at most this many calls of ``along_at`` (>= 1; the first is at 1).
        bounds: ``(low, high)`` paces the search stays within (``0 < low <= 1 <= high``).
    Returns:
        ``{"pace", "along_r", "evaluations": [[pace, along_r], ...], "track_length_r"}``.
    """
    low, high = bounds
    if not 0 < low <= 1.0 <= high:
        raise ConfigError(f"pace fit: bounds must satisfy 0 < low <= 1 <= high, got {bounds}")
    if not track_length_r > 0:
        raise ConfigError(f"pace fit: the true clot does not move along its track "
                          f"(length {track_length_r} r); there is no pace to fit")
    if max_evals < 1:
        raise ConfigError(f"pace fit: max_evals must be >= 1, got {max_evals}")
    evals = [(1.0, float(along_at(1.0)))]
    while abs(evals[-1][1]) > tol_r and len(evals) < max_evals:
        (p0, e0), (p1, e1) = (evals[-2] if len(evals) > 1 else (None, None)), evals[-1]
        if p0 is None or e1 == e0:  # the ratio of the true path to the model's
            nxt = p1 * track_length_r / max(track_length_r + e1, 1e-6 * track_length_r)
        else:  # secant
            nxt = p1 - e1 * (p1 - p0) / (e1 - e0)
        nxt = float(np.clip(nxt, low, high))
        if any(abs(nxt - p) < 1e-6 for p, _ in evals):  # pinned at a bound, or converged
            break
        evals.append((nxt, float(along_at(nxt))))
    best = min(evals, key=lambda pe: abs(pe[1]))
    return {"pace": best[0], "along_r": best[1], "evaluations": [list(e) for e in evals],
            "track_length_r": float(track_length_r)}


def fit_pace_on_simulations(
    step, params, stats, simulations: Sequence[tuple[str, np.ndarray, np.ndarray, object]], *,
    radius: float, t0: int, n_nodes: int | None, ensemble: bool,
    centring_r: float | None = None, seed: int = 0, tol_r: float = 0.05, max_evals: int = 5,
) -> dict:
    """:func:`fit_pace` with guarded rollouts of a model on ``simulations``.

    Args:
        step, params, stats: the learned step and its parameters (member-stacked when
            ``ensemble``) and statistics, as :func:`thrombojax.eval.rollouts.rollout_simulation`.
        simulations: ``(name, scaled positions [T, N, 3], node_type [N], wall_cells or None)``
            per simulation; the fit zeroes their mean final along-track error.
        radius: one vessel radius in scaled coordinates.
        t0, n_nodes, seed, ensemble, centring_r: the rollout's, as the rollout that uses the
            pace (the fit must see the same rollout).
        tol_r, max_evals: :func:`fit_pace`'s.
    Returns:
        :func:`fit_pace`'s dict plus ``"simulations"`` (their names).
    """
    if not simulations:
        raise ConfigError("pace fit: no simulation to fit the pace on")

    def along_at(pace: float) -> float:
        errors = []
        for name, positions, node_type, wall_cells in simulations:
            res = rollout_simulation(step, params, stats, positions, node_type, name=name,
                                     t0=t0, n_nodes=n_nodes, seed=seed, wall_cells=wall_cells,
                                     guard_radius=radius, ensemble=ensemble,
                                     centring_r=centring_r, pace=pace)
            along, _ = track_errors(res.pred, res.true, clot_mask(res.node_type),
                                    start=res.initial[1])
            errors.append(float(along[-1]) / radius)
        return float(np.mean(errors))

    lengths = [float(centroid_speed(np.asarray(positions)[t0:], clot_mask(np.asarray(nt))).sum())
               / radius for _, positions, nt, _ in simulations]
    fit = fit_pace(along_at, float(np.mean(lengths)), tol_r=tol_r, max_evals=max_evals)
    return fit | {"simulations": [s[0] for s in simulations]}
