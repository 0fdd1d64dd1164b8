"""The built-in numerical solver: a soft clot driven through a rigid vessel (explicit FEM, JAX).

``geometry`` (centrelines, wall rings, signed distance), ``clot`` (tet mesh, placement),
``material`` (Neo-Hookean, averaged nodal pressure), ``solver`` (jitted explicit dynamics,
contact, friction), ``cases`` (preset + seed -> case), ``presets``, ``generate`` (datasets).
"""

from thrombojax.sim.generate import generate_dataset, simulate
from thrombojax.sim.presets import PRESETS, Preset, get_preset

__all__ = ["PRESETS", "Preset", "get_preset", "simulate", "generate_dataset"]
