"""thrombojax: fast learned surrogates of mechanical-thrombectomy simulations.

The public API, re-exported explicitly (each name from the module that defines it)::

    import thrombojax as tj
    tj.generate_dataset("bendvessel", "bv.h5")            # the built-in JAX FEM solver
    ds = tj.open_dataset("bv.h5")                          # the one dataset schema
    trained = tj.train("bv.h5", "mgn", "runs/mgn")         # AdamW, checkpoints, resume
    traj = tj.rollout(trained.step, trained.params, trained.stats, x_prev, x0, node_type,
                      mask, n_steps)                       # one compiled lax.scan

Names are imported lazily on first access (PEP 562), so ``thrombojax --help`` and
``import thrombojax`` stay fast; ``__all__`` lists every public name.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_EXPORTS: dict[str, str] = {
    # types and errors
    "NodeType": "thrombojax.types",
    "ModelInput": "thrombojax.types",
    "TargetStats": "thrombojax.types",
    "ThrombojaxError": "thrombojax.errors",
    "DatasetError": "thrombojax.errors",
    "ConfigError": "thrombojax.errors",
    "CapacityOverflowError": "thrombojax.errors",
    # solver
    "generate_dataset": "thrombojax.sim.generate",
    "simulate": "thrombojax.sim.generate",
    "get_preset": "thrombojax.sim.presets",
    # datasets and data
    "Simulation": "thrombojax.io.hdf5",
    "DatasetWriter": "thrombojax.io.hdf5",
    "open_dataset": "thrombojax.io.hdf5",
    "write_dataset": "thrombojax.io.hdf5",
    "validate_simulation": "thrombojax.io.hdf5",
    "Scaling": "thrombojax.data.scaling",
    "fit_scaling": "thrombojax.data.scaling",
    "split_simulations": "thrombojax.data.splits",
    # graphs
    "radius_graph": "thrombojax.graph.neighbors",
    "NeighborList": "thrombojax.graph.neighbors",
    "build_balltree": "thrombojax.graph.balltree",
    # models
    "MODEL_NAMES": "thrombojax.models.registry",
    "create_model": "thrombojax.models.registry",
    "get_config": "thrombojax.models.registry",
    # training
    "train": "thrombojax.train.loop",
    "load_trained": "thrombojax.train.state",
    "TrainedModel": "thrombojax.train.state",
    "subsample_indices": "thrombojax.data.augment",
    # the learned simulator
    "LearnedStep": "thrombojax.simulator.step",
    "make_step": "thrombojax.simulator.step",
    "allocate_grid": "thrombojax.simulator.grid_step",
    "rollout": "thrombojax.simulator.rollout",
    "constant_velocity_rollout": "thrombojax.simulator.rollout",
    # training
    "TrainConfig": "thrombojax.train.config",
    "RunConfig": "thrombojax.train.config",
    # evaluation
    "evaluate_run": "thrombojax.eval.single_step",
    "rollout_simulation": "thrombojax.eval.rollouts",
    "rollout_run": "thrombojax.eval.report",
    "bench": "thrombojax.eval.bench",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'thrombojax' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
