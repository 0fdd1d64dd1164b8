"""One isotropic affine map per dataset from physical units to [-1, 1].

``y = (x - center) / scale`` with a single scale for all three axes, so rotations, angles and
distance ratios keep their meaning (a radius graph in scaled coordinates is a radius graph in
physical ones). :func:`fit_scaling` takes ``center`` = the midpoint of the bounding box of all
frames of all simulations and ``scale`` = half its largest side, enlarged by the factor
``1 + 1e-6`` so float32 round-off can never put a node outside [-1, 1]. The map is stored with
every trained model (``to_dict`` / ``from_dict``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import jax
import numpy as np
from flax import struct

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.io.schema import bounding_box

__all__ = ["Scaling", "fit_scaling", "SCALE_MARGIN"]

SCALE_MARGIN: float = 1e-6
"""Relative enlargement of the fitted scale (keeps float32 results inside [-1, 1])."""


def _use_jax(*xs: Any) -> bool:
    return any(isinstance(x, jax.Array) for x in xs)


@struct.dataclass
class Scaling:
    """The isotropic map ``y = (x - center) / scale`` (a pytree; passes through ``jit``).

    Attributes:
        center: ``[3]`` float (float64 numpy when fitted; float32 under ``jit``).
        scale: ``[]`` float, > 0, one factor for all axes.
    """

    center: Any
    scale: Any

    def apply(self, x: Any) -> Any:
        """Physical -> scaled positions, ``[..., 3]``; numpy in float64 then the input dtype."""
        if _use_jax(x, self.center, self.scale):
            return (x - self.center) / self.scale
        x = np.asarray(x)
        y = (x.astype(np.float64) - np.asarray(self.center)) / np.asarray(self.scale)
        return y.astype(_out_dtype(x))

    def invert(self, y: Any) -> Any:
        """Scaled -> physical positions, ``[..., 3]``."""
        if _use_jax(y, self.center, self.scale):
            return y * self.scale + self.center
        y = np.asarray(y)
        x = y.astype(np.float64) * np.asarray(self.scale) + np.asarray(self.center)
        return x.astype(_out_dtype(y))

    def apply_vector(self, v: Any) -> Any:
        """Physical -> scaled displacements / velocities (no shift), ``[..., 3]``."""
        if _use_jax(v, self.scale):
            return v / self.scale
        v = np.asarray(v)
        return (v.astype(np.float64) / np.asarray(self.scale)).astype(_out_dtype(v))

    def invert_vector(self, w: Any) -> Any:
        """Scaled -> physical displacements / velocities, ``[..., 3]``."""
        if _use_jax(w, self.scale):
            return w * self.scale
        w = np.asarray(w)
        return (w.astype(np.float64) * np.asarray(self.scale)).astype(_out_dtype(w))

    def to_dict(self) -> dict:
        """JSON-ready ``{"center": [3 floats], "scale": float}``."""
        return {
            "center": [float(c) for c in np.asarray(self.center, np.float64)],
            "scale": float(np.asarray(self.scale, np.float64)),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Scaling:
        """Inverse of :meth:`to_dict`; raises ConfigError on a malformed dict."""
        try:
            center = np.asarray(d["center"], np.float64)
            scale = np.asarray(d["scale"], np.float64)
        except (KeyError, TypeError, ValueError) as err:
            expected = "{'center': [3 floats], 'scale': float}"
            raise ConfigError(f"scaling: expected {expected}, got {d!r}") from err
        if center.shape != (3,) or scale.shape != () or not np.isfinite(center).all():
            raise ConfigError(f"scaling: bad center {center} or scale {scale}")
        if not (np.isfinite(scale) and scale > 0):
            raise ConfigError(f"scaling: scale must be finite and > 0, got {scale}")
        return cls(center=center, scale=scale)


def _out_dtype(x: np.ndarray) -> np.dtype:
    return x.dtype if x.dtype.kind == "f" else np.dtype(np.float32)


def fit_scaling(
    data: Any, *, names: Sequence[str] | None = None, margin: float = SCALE_MARGIN
) -> Scaling:
    """Fit one isotropic map to [-1, 1] over every frame of every simulation.

    Args:
        data: a :class:`~thrombojax.io.hdf5.Dataset` (read one simulation at a time), a single
            ``[T, N, 3]`` / ``[N, 3]`` array, or an iterable of such arrays.
        names: for a Dataset, the simulations to fit on (default: all).
        margin: relative enlargement of the scale (module docstring).
    Returns:
        The :class:`Scaling` (center float64 ``[3]``, scale float64 ``[]``).
    Raises:
        DatasetError: no positions, non-finite values, or zero extent.
    """
    arrays: Iterable[Any]
    if hasattr(data, "positions") and hasattr(data, "names"):
        arrays = (data.positions(n) for n in (data.names if names is None else names))
    elif isinstance(data, np.ndarray | jax.Array):
        arrays = [data]
    else:
        arrays = data
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for i, arr in enumerate(arrays):
        arr = np.asarray(arr)
        if arr.ndim < 2 or arr.shape[-1] != 3:
            raise DatasetError(f"fit_scaling: array {i} has shape {arr.shape}, expected [..., 3]")
        if arr.size == 0:
            continue
        if not np.isfinite(arr).all():
            raise DatasetError(f"fit_scaling: array {i} holds non-finite positions")
        arr_lo, arr_hi = bounding_box(arr)
        lo, hi = np.minimum(lo, arr_lo), np.maximum(hi, arr_hi)
    if not np.isfinite(lo).all():
        raise DatasetError("fit_scaling: no positions to fit")
    half = float((hi - lo).max()) / 2.0
    if half <= 0.0:
        raise DatasetError("fit_scaling: all positions coincide (zero extent)")
    return Scaling(center=(lo + hi) / 2.0, scale=np.asarray(half * (1.0 + margin), np.float64))
