"""Errors in vessel radii: the conversion from the scaled [-1, 1] coordinates, recorded with it.

A run maps the dataset's positions ``x`` (its length unit) to ``scaled = (x - center) / scale``
(:mod:`thrombojax.data.scaling`), so one scaled unit is ``scale`` dataset units, and one vessel
radius is ``r`` dataset units (:func:`thrombojax.data.radius.vessel_radius`). Hence

- a length (centroid error, RMSE) in radii = ``length_scaled * scale / r``;
- an MSE in radii squared = ``MSE_scaled * (scale / r) ** 2``;
- an RMSE in radii = ``sqrt(MSE_scaled) * scale / r`` (the root of the mean over clot nodes and
  x, y, z of the squared error: a per-coordinate RMS, ``1/sqrt(3)`` of the RMS node distance).

Ratios to constant velocity (model / CV) are the same in every unit. Every report records
:meth:`RadiusUnits.to_dict` beside its numbers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from thrombojax.data.radius import vessel_radius_and_source
from thrombojax.data.scaling import Scaling

__all__ = ["RadiusUnits", "radius_units", "ratio", "summary_in_radii", "curves_in_radii"]

CV_LABEL = "constant velocity"


@dataclasses.dataclass(frozen=True)
class RadiusUnits:
    """The map from scaled coordinates to vessel radii of one run on one dataset.

    Attributes:
        scale: dataset length units per scaled unit (the run's ``Scaling.scale``).
        radius: dataset length units per vessel radius.
        source: where ``radius`` came from (:func:`thrombojax.data.radius.vessel_radius`).
        units: the dataset's length unit (``""`` when not recorded).
    """

    scale: float
    radius: float
    source: str
    units: str = ""

    @property
    def factor(self) -> float:
        """Vessel radii per scaled unit, ``scale / radius``."""
        return self.scale / self.radius

    def length(self, scaled: Any) -> Any:
        """A length (float, or ``[...]`` array) in scaled units -> vessel radii."""
        return _same_kind(np.asarray(scaled, np.float64) * self.factor)

    def mse(self, mse_scaled: Any) -> Any:
        """An MSE (float, or ``[...]`` array) in scaled units squared -> radii squared."""
        return _same_kind(np.asarray(mse_scaled, np.float64) * self.factor**2)

    def rmse(self, mse_scaled: Any) -> Any:
        """An MSE (float, or ``[...]`` array) in scaled units squared -> RMSE in radii."""
        return _same_kind(np.sqrt(np.asarray(mse_scaled, np.float64)) * self.factor)

    def to_dict(self) -> dict:
        """JSON-ready record of the conversion (the numbers and the formulas)."""
        unit = self.units or "dataset units"
        return {
            "dataset_units": self.units,
            "vessel_radius": self.radius,
            "vessel_radius_source": self.source,
            "scale": self.scale,
            "radii_per_scaled_unit": self.factor,
            "formula": (f"scaled = (x - center) / scale; r = {self.radius:.6g} {unit}, scale = "
                        f"{self.scale:.6g} {unit}; length_r = length_scaled * scale / r; "
                        "MSE_r2 = MSE_scaled * (scale / r)^2; RMSE_r = sqrt(MSE_scaled) * "
                        "scale / r"),
        }

    def describe(self) -> str:
        """One markdown line stating the conversion."""
        unit = self.units or "dataset units"
        return (f"Vessel radius r = {self.radius:.4g} {unit} ({self.source}); one scaled unit = "
                f"{self.factor:.4g} r (scale {self.scale:.4g} {unit}); MSE in r^2 = scaled MSE "
                f"x {self.factor ** 2:.4g}; RMSE in r = sqrt(scaled MSE) x {self.factor:.4g}.")


def _same_kind(x: np.ndarray) -> Any:
    """A 0-d array as a Python float (JSON-ready), else the array."""
    return float(x) if x.ndim == 0 else x


def radius_units(scaling: Scaling, dataset: Any) -> RadiusUnits:
    """The conversion of a run (its scaling) on a dataset (its vessel radius and unit).

    Args:
        scaling: the run's :class:`~thrombojax.data.scaling.Scaling` (``scale`` in dataset units).
        dataset: the open :class:`thrombojax.io.hdf5.Dataset` being evaluated.
    """
    r, source = vessel_radius_and_source(dataset)
    return RadiusUnits(scale=float(np.asarray(scaling.scale, np.float64)), radius=float(r),
                       source=source, units=str(getattr(dataset, "attrs", {}).get("units", "")))


def ratio(model: float | None, baseline: float | None) -> float | None:
    """``model / baseline``; ``None`` when either is missing or the baseline is 0."""
    if model is None or baseline is None or not baseline:
        return None
    return float(model) / float(baseline)


def summary_in_radii(summary: Mapping[str, Mapping[str, float]], units: RadiusUnits,
                     *, baseline: str = CV_LABEL) -> dict:
    """Add vessel-radius values and ratios to constant velocity to a rollout summary.

    Args:
        summary: label -> ``{"mse@h": scaled MSE, "final_centroid_error": scaled length,
            "max_fraction_outside": ...}`` (:func:`thrombojax.eval.rollouts.rollout_simulation`).
        units: the conversion.
        baseline: the label every other label is divided by.
    Returns:
        A new dict: every ``mse@h`` gains ``mse@h_r2`` and ``rmse@h_r``, the centroid error
        ``final_centroid_error_r``; every label but the baseline (and the ground truth) gains
        ``ratio_to_cv``: ``{"mse@h": model / CV, "final_centroid_error": model / CV}``.
    """
    out = {}
    for label, s in summary.items():
        s = dict(s)
        for key in [k for k in s if k.startswith("mse@")]:
            s[f"{key}_r2"] = units.mse(s[key])
            s[f"r{key}_r"] = units.rmse(s[key])
        if "final_centroid_error" in s:
            s["final_centroid_error_r"] = units.length(s["final_centroid_error"])
        out[label] = s
    base = summary.get(baseline, {})
    for label, s in out.items():
        if label != baseline and "final_centroid_error" in s:
            keys = [k for k in s if k.startswith("mse@") and "_r" not in k]
            s["ratio_to_cv"] = {k: ratio(s[k], base.get(k))
                                for k in [*keys, "final_centroid_error"]}
    return out


def curves_in_radii(curves: Mapping[str, Mapping[str, np.ndarray]],
                    units: RadiusUnits) -> dict:
    """Per-step curves with their vessel-radius versions added (JSON-ready lists).

    Args:
        curves: label -> ``{"mse": [n_steps] scaled, "centroid_error": [n_steps] scaled, ...}``.
    Returns:
        label -> the same lists plus ``rmse_r`` and ``centroid_error_r`` ``[n_steps]``.
    """
    out = {}
    for label, c in curves.items():
        d = {k: np.asarray(v).tolist() for k, v in c.items()}
        if "mse" in c:
            d["rmse_r"] = units.rmse(np.asarray(c["mse"])).tolist()
        if "centroid_error" in c:
            d["centroid_error_r"] = units.length(np.asarray(c["centroid_error"])).tolist()
        out[label] = d
    return out
