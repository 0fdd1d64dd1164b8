"""The vessel radius of a dataset, in its own length unit: the physical scale of every error.

Errors are reported, and training noise is set, in vessel radii (r). :func:`vessel_radius`
reads the dataset's ``vessel_radius`` file attribute when it has one; a dataset in the unit
``vessel radius`` (the built-in solver's) has r = 1; otherwise r is estimated from the geometry:
at frame 0 the clot fills the lumen where it sits, so the largest distance from a clot node to
its nearest vessel node is about one radius (median over the simulations).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from thrombojax.errors import DatasetError
from thrombojax.types import NodeType

__all__ = ["vessel_radius", "estimate_vessel_radius"]


def estimate_vessel_radius(positions0: np.ndarray, node_type: np.ndarray) -> float:
    """Largest distance from a clot node to its nearest vessel node at one frame.

    Args:
        positions0: ``[N, 3]`` one frame. node_type: ``[N]`` NodeType values.
    Returns:
        The estimate, in the positions' unit.
    """
    pos = np.asarray(positions0, np.float64)
    clot = np.asarray(node_type) == NodeType.CLOT
    if not clot.any() or clot.all():
        raise DatasetError("vessel radius: a frame needs clot and vessel nodes")
    dist, _ = cKDTree(pos[~clot]).query(pos[clot])
    return float(dist.max())


def vessel_radius(dataset: Any) -> float:
    """One vessel radius in the dataset's length unit (see the module docstring).

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`.
    """
    attrs = dataset.attrs
    if "vessel_radius" in attrs:
        value = float(attrs["vessel_radius"])
        if not value > 0:
            raise DatasetError(f"{getattr(dataset, 'path', '<dataset>')}: field 'vessel_radius': "
                               f"must be > 0, got {value}")
        return value
    if str(attrs.get("units", "")).strip().lower() == "vessel radius":
        return 1.0
    radii = [estimate_vessel_radius(dataset.positions(name, 0), dataset.node_type(name))
             for name in dataset.names]
    return float(np.median(radii))
