"""Surrogate models: MeshGraphNet, Transolver, Erwin and a constant-velocity baseline.

Build them by name with :func:`create_model`; the model classes live in their own modules
(imported on demand). Every surrogate follows the contract of :mod:`thrombojax.models.registry`.
"""

from thrombojax.models.registry import (
    ALIASES,
    MODEL_NAMES,
    MODEL_SPECS,
    ConstantVelocity,
    ConstantVelocityConfig,
    ErwinConfig,
    FlaxSurrogate,
    MeshGraphNetConfig,
    ModelSpec,
    Surrogate,
    TransolverConfig,
    canonical_name,
    config_from_dict,
    config_to_dict,
    count_params,
    create_model,
    get_config,
    identity_stats,
)

__all__ = [
    "ALIASES",
    "MODEL_NAMES",
    "MODEL_SPECS",
    "ConstantVelocity",
    "ConstantVelocityConfig",
    "ErwinConfig",
    "FlaxSurrogate",
    "MeshGraphNetConfig",
    "ModelSpec",
    "Surrogate",
    "TransolverConfig",
    "canonical_name",
    "config_from_dict",
    "config_to_dict",
    "count_params",
    "create_model",
    "get_config",
    "identity_stats",
]
