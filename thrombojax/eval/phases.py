"""Single-step errors split by the phase of the simulation they fall in, beside constant velocity.

One headline single-step MSE hides where a model helps: a clot starting from rest (where
constant velocity, CV, cannot know the coming acceleration) and a clot leaving the vessel are
easy wins, the frames in between are where rollouts run. A window ``(s_{t-1}, s_t, s_{t+1})``
(middle frame ``t``, target ``t + 1``) belongs to:

- ``start``: ``t < skip_frames``, the dataset's ``skip_frames`` attribute
  (:func:`thrombojax.study.skip_frames`): the clot starts from rest; rollouts skip these frames;
- ``rollout``: ``t >= skip_frames``, every window a rollout predicts;
- ``exit``: ``t + 1 >= exit_frame``, where :func:`exit_frame` is the first frame in which a true
  clot node lies past an open end of the vessel that it did not lie past at frame 0 (its nearest
  wall node is on the rim of :func:`thrombojax.eval.metrics.fit_vessel_wall`, from the wall
  triangles when the dataset has them, it lies beyond it, and no wall node lies further out
  around it): the clot passing the outlet
  and what follows; empty when the clot never leaves. Nodes past an open end at frame 0 (a clot
  that enters through the inlet) do not count;
- ``rollout_before_exit``: ``rollout`` windows that are not ``exit`` windows: the phase the
  model must beat CV in for its rollouts to be of use;
- ``all``: every window.

Each phase reports its window count, the mean MSE of the model and of CV (scaled units and
vessel radii, :mod:`thrombojax.eval.physical`) and the ratio model / CV. Means are over windows
(each window's MSE is a mean over clot nodes and x, y, z).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from thrombojax.eval.metrics import VesselWall
from thrombojax.eval.physical import RadiusUnits, ratio

__all__ = [
    "PHASES",
    "PHASE_HELP",
    "exit_frame",
    "window_phases",
    "phase_summary",
]

PHASES: tuple[str, ...] = ("all", "start", "rollout", "rollout_before_exit", "exit")

PHASE_HELP: dict[str, str] = {
    "all": "every window",
    "start": "t < skip_frames (clot starting from rest)",
    "rollout": "t >= skip_frames (the frames rollouts predict)",
    "rollout_before_exit": "t >= skip_frames, before the clot reaches the outlet",
    "exit": "target frame >= the first frame with a clot node past the vessel's open end "
            "(no wall node further out around it)",
}


def exit_frame(wall: VesselWall, positions: np.ndarray, clot_mask: np.ndarray, *,
               margin: float = 0.0, k: int = 16) -> int | None:
    """First frame in which a true clot node is past an open vessel end it was not past at 0.

    A node is past an open end when its nearest wall node lies on the rim (``rim_dir`` of
    :func:`thrombojax.eval.metrics.fit_vessel_wall`), the node lies beyond that rim node along
    the rim's outward in-surface direction by more than ``margin``, and none of its ``k``
    nearest wall nodes lies further in that direction (the wall does not go on: this rejects the
    few false rim nodes that the angular-gap test finds inside sparse or irregular wall clouds).

    Args:
        wall: the fitted vessel wall (:func:`thrombojax.eval.metrics.fit_vessel_wall`), in the
            coordinates of ``positions``.
        positions: ``[T, N, 3]`` the true trajectory. clot_mask: ``[N]`` bool.
        margin: distance past the rim that counts (same unit as ``positions``).
        k: wall nodes around each clot node that must all lie behind it.
    Returns:
        The frame index in ``1 .. T - 1``, or ``None`` when the clot never leaves.
    """
    clot = np.asarray(positions, np.float64)[:, np.asarray(clot_mask, bool)]  # [T, n, 3]
    flat = clot.reshape(-1, 3)
    _, near = cKDTree(wall.points).query(flat, k=min(k, wall.points.shape[0]))
    near = near.reshape(flat.shape[0], -1)
    out = wall.rim_dir[near[:, 0]]  # [T * n, 3]; zero off the rim
    beyond = np.einsum("nj,nj->n", flat - wall.points[near[:, 0]], out)
    ahead = np.einsum("nkj,nj->nk", wall.points[near] - flat[:, None], out).max(axis=1)
    past = ((beyond > margin) & (ahead <= 0)).reshape(clot.shape[:2])  # [T, n]
    leaving = (past[1:] & ~past[:1]).any(axis=1)
    return int(np.argmax(leaving)) + 1 if leaving.any() else None


def window_phases(times: np.ndarray, *, skip_frames: int,
                  exit_at: int | None) -> dict[str, np.ndarray]:
    """Phase masks of windows with middle frames ``times`` (module docstring).

    Args:
        times: ``[W]`` middle frames ``t`` of the windows. skip_frames: the dataset's attribute.
        exit_at: :func:`exit_frame` (``None``: no exit phase).
    Returns:
        phase name -> ``[W]`` bool, for every name in :data:`PHASES`.
    """
    t = np.asarray(times)
    exit_ = np.zeros(t.shape, bool) if exit_at is None else t + 1 >= exit_at
    rollout = t >= skip_frames
    return {"all": np.ones(t.shape, bool), "start": ~rollout, "rollout": rollout,
            "rollout_before_exit": rollout & ~exit_, "exit": exit_}


def phase_summary(model: np.ndarray, baseline: np.ndarray, phases: dict[str, np.ndarray],
                  units: RadiusUnits) -> dict[str, dict]:
    """Mean single-step MSE per phase, model beside constant velocity, scaled and in radii.

    Args:
        model, baseline: ``[W]`` MSE per window (scaled units squared) of the model and of CV.
        phases: phase -> ``[W]`` bool (:func:`window_phases`).
        units: the conversion to vessel radii.
    Returns:
        phase -> ``{"windows", "mse", "constant_velocity_mse", "ratio_to_cv", "mse_r2",
        "constant_velocity_mse_r2", "rmse_r", "constant_velocity_rmse_r"}`` (values ``None``
        for a phase without windows).
    """
    out = {}
    for name in PHASES:
        sel = np.asarray(phases[name], bool)
        n = int(sel.sum())
        m = float(np.mean(model[sel])) if n else None
        b = float(np.mean(baseline[sel])) if n else None
        out[name] = {
            "windows": n, "mse": m, "constant_velocity_mse": b, "ratio_to_cv": ratio(m, b),
            "mse_r2": units.mse(m) if n else None,
            "constant_velocity_mse_r2": units.mse(b) if n else None,
            "rmse_r": units.rmse(m) if n else None,
            "constant_velocity_rmse_r": units.rmse(b) if n else None,
        }
    return out
