"""Model registry: one frozen config dataclass per surrogate and one contract for all of them.

Every surrogate (MeshGraphNet, Transolver, Erwin, the constant-velocity baseline) is a frozen
dataclass with ``name`` and ``config`` and three pure methods, all for ONE sample (no batch axis;
batch with ``jax.vmap``) and all jittable with the surrogate as a static argument:

    graph  = model.build_graph(inputs)                 # radius graph / ball tree from s_t
    params = model.init(rng, inputs, graph)            # Flax variables dict ({} for the baseline)
    out    = model.apply(params, inputs, graph, train=False, rng=None)   # [n_nodes, 3]

``out`` is the normalised acceleration ``(a - mean) / std`` (:class:`thrombojax.types.TargetStats`);
padded nodes' outputs are finite but arbitrary and must be masked downstream. ``graph`` is any
pytree. Each node keeps its ``max_neighbors`` nearest within the radius (the model's definition,
like torch_cluster's cap). ``build_graph(inputs, grid=spec)`` passes a static
:class:`~thrombojax.graph.grid.GridSpec` to the radius search, whose ``"auto"`` method then uses
the cell grid where it pays (large clouds) and the exact dense search elsewhere; the grid's
``overflow`` flag stays in the graph (:func:`thrombojax.graph.neighbors.graph_overflow`) and the
learned step returns it (:mod:`thrombojax.simulator.grid_step` re-allocates on the host).

Config defaults are the study's architecture hyper-parameters; configs hold architecture only
(the study's batch sizes and learning rates are training settings: :mod:`thrombojax.study`).
The config classes live in :mod:`thrombojax.models.configs` and are re-exported here.

One learned step runs a surrogate (:mod:`thrombojax.simulator.step`); nothing else calls
``build_graph`` / ``apply`` in sequence.

Adding a model: append a :class:`ModelSpec` to :data:`MODEL_SPECS` naming its config class, the
module that defines it (imported lazily, on :func:`create_model`) and the surrogate class there.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from typing import Any, ClassVar, Protocol

import flax.linen as nn
import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.errors import ConfigError
from thrombojax.graph.grid import GridSpec
from thrombojax.graph.neighbors import radius_graph
from thrombojax.models.configs import (
    ConstantVelocityConfig,
    ErwinConfig,
    MeshGraphNetConfig,
    TransolverConfig,
)
from thrombojax.models.grouped_init import grouped_init
from thrombojax.types import ModelInput, TargetStats

__all__ = [
    "MeshGraphNetConfig", "TransolverConfig", "ErwinConfig", "ConstantVelocityConfig",
    "Surrogate", "FlaxSurrogate", "ConstantVelocity", "EmptyGraph", "ModelSpec",
    "MODEL_SPECS", "MODEL_NAMES", "ALIASES", "canonical_name", "get_config", "create_model",
    "config_to_dict", "config_from_dict", "count_params", "identity_stats",
]  # fmt: skip


# ---- the contract -------------------------------------------------------------------------


class Surrogate(Protocol):
    """What every model returned by :func:`create_model` provides (see the module docstring)."""

    name: str
    config: Any

    def build_graph(self, inputs: ModelInput, grid: GridSpec | None = None) -> Any: ...
    def init(self, rng: jax.Array, inputs: ModelInput, graph: Any) -> dict: ...
    def apply(self, params: dict, inputs: ModelInput, graph: Any, *, train: bool = False,
              rng: jax.Array | None = None) -> jax.Array: ...


@dataclasses.dataclass(frozen=True)
class FlaxSurrogate:
    """Shared implementation of the contract for a Flax module ``module_cls(config=...)``.

    The module is called as ``module(inputs, graph, train=train)`` and returns ``[n_nodes, 3]``;
    dropout draws from the ``"dropout"`` RNG stream. The default graph is the padded radius graph
    (:func:`thrombojax.graph.neighbors.radius_graph`) of ``config.radius`` / ``max_neighbors`` on
    the real nodes, with self loops when ``self_loops`` (Erwin's and Transolver's embedding, as
    ``torch_cluster.radius_graph(loop=True)`` in the official Erwin code); subclasses with other
    graphs (Erwin's ball tree) override :meth:`build_graph`.

    Attributes:
        name: canonical registry name.
        config: the model's config dataclass.
        graph_local (class attribute): every interaction between nodes goes through the radius
            graph (a :class:`~thrombojax.graph.neighbors.NeighborList`), so the model may run a
            batch as one flat graph (:mod:`thrombojax.simulator.flat`); False where a model
            mixes all nodes of a sample (attention, a ball tree).
        rest_edges (class attribute): the model's edges read the rest-state displacement of
            ``ModelInput.rest`` when it is set (``make_step(..., rest_edges=True)``).
    """

    name: str
    config: Any
    module_cls: ClassVar[type[nn.Module]]
    self_loops: ClassVar[bool] = False
    graph_local: ClassVar[bool] = False
    rest_edges: ClassVar[bool] = False

    @property
    def module(self) -> nn.Module:
        """The Flax module built from the config."""
        return self.module_cls(config=self.config)

    def build_graph(self, inputs: ModelInput, grid: GridSpec | None = None) -> Any:
        """Radius graph of the real nodes: a ``NeighborList`` (``indices [N, K]``, ``counts``);
        the cell ``grid`` (static) is used where it pays, else the dense search."""
        cfg = self.config
        return radius_graph(inputs.positions, cfg.radius, cfg.max_neighbors, mask=inputs.mask,
                            loop=self.self_loops, grid=grid)

    def init(self, rng: jax.Array, inputs: ModelInput, graph: Any) -> dict:
        """Initialise the variables ``{"params": ...}`` (compiled: faster than eager Flax init)."""
        return _init_flax(self, rng, inputs, graph)

    def apply(self, params: dict, inputs: ModelInput, graph: Any, *, train: bool = False,
              rng: jax.Array | None = None) -> jax.Array:
        """Normalised acceleration ``[n_nodes, 3]``; ``rng`` is needed to train with dropout.

        Called outside a trace it runs as one compiled program (not op by op); inside ``jit``,
        ``grad``, ``vmap`` or ``scan`` it is inlined into the caller's program."""
        if train and rng is None and getattr(self.config, "dropout", 0.0) > 0.0:
            raise ConfigError(f"model '{self.name}': apply(train=True) uses dropout and needs rng")
        return _apply_flax(self, params, inputs, graph, train, rng)


@functools.partial(jax.jit, static_argnums=(0, 4), inline=True)
def _apply_flax(model: FlaxSurrogate, params: dict, inputs: ModelInput, graph: Any, train: bool,
                rng: jax.Array | None) -> jax.Array:
    rngs = {} if rng is None else {"dropout": rng}
    return model.module.apply(params, inputs, graph, train=train, rngs=rngs)


@functools.partial(jax.jit, static_argnums=0)
def _init_flax(model: FlaxSurrogate, rng: jax.Array, inputs: ModelInput, graph: Any) -> dict:
    params_rng, dropout_rng = jax.random.split(rng)
    rngs = {"params": params_rng, "dropout": dropout_rng}
    return grouped_init(model.module, rngs, inputs, graph, train=False)


@struct.dataclass
class EmptyGraph:
    """The graph of a model that needs none (an empty pytree)."""


@dataclasses.dataclass(frozen=True)
class ConstantVelocity:
    """Baseline ``s_{t+1} = s_t + v_t``: predicts zero acceleration, has no parameters.

    ``apply`` returns zeros, i.e. a zero *normalised* acceleration. To get zero physical
    acceleration, integrate it with :func:`identity_stats` (``TargetStats(mean=0, std=1)``), e.g.
    ``make_step(model)({}, identity_stats(), ...)``; with a dataset's statistics the zeros would
    denormalise to the mean acceleration instead.
    """

    name: str
    config: ConstantVelocityConfig

    def build_graph(self, inputs: ModelInput, grid: GridSpec | None = None) -> EmptyGraph:
        return EmptyGraph()

    def init(self, rng: jax.Array, inputs: ModelInput, graph: Any) -> dict:
        return {}

    def apply(self, params: dict, inputs: ModelInput, graph: Any, *, train: bool = False,
              rng: jax.Array | None = None) -> jax.Array:
        return jnp.zeros_like(inputs.velocity)


def identity_stats() -> TargetStats:
    """``TargetStats(mean=0, std=1)``: the statistics to use with :class:`ConstantVelocity`."""
    return TargetStats(mean=jnp.zeros(3, jnp.float32), std=jnp.ones(3, jnp.float32))


# ---- the registry -------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """One registry entry: the config class and where the surrogate class lives (lazy import).

    Attributes:
        config_cls: the config dataclass.
        module: dotted module path of the surrogate class.
        surrogate: class name in that module; called as ``cls(name=..., config=...)``.
    """

    config_cls: type
    module: str
    surrogate: str


_PKG = "thrombojax.models"
MODEL_SPECS: dict[str, ModelSpec] = {
    "mgn": ModelSpec(MeshGraphNetConfig, f"{_PKG}.meshgraphnet", "MeshGraphNetSurrogate"),
    "transolver": ModelSpec(TransolverConfig, f"{_PKG}.transolver", "TransolverSurrogate"),
    "erwin": ModelSpec(ErwinConfig, f"{_PKG}.erwin", "ErwinSurrogate"),
    "constant_velocity": ModelSpec(ConstantVelocityConfig, __name__, "ConstantVelocity"),
}
MODEL_NAMES: tuple[str, ...] = tuple(MODEL_SPECS)
ALIASES: dict[str, str] = {"meshgraphnet": "mgn", "constant-velocity": "constant_velocity"}


def canonical_name(name: str) -> str:
    """Resolve aliases (case-insensitive); unknown names raise :class:`ConfigError`."""
    key = ALIASES.get(name.lower(), name.lower())
    if key not in MODEL_SPECS:
        known = ", ".join(list(MODEL_SPECS) + list(ALIASES))
        raise ConfigError(f"unknown model '{name}'; known models: {known}")
    return key


def _coerce(config_cls: type, values: dict, name: str) -> dict:
    """Check field names; JSON lists become tuples where the field is a tuple."""
    fields = sorted(f.name for f in dataclasses.fields(config_cls))
    if unknown := sorted(set(values) - set(fields)):
        raise ConfigError(f"model '{name}': unknown config field(s) {unknown}; known: {fields}")
    defaults = config_cls()
    return {k: tuple(v) if isinstance(getattr(defaults, k), tuple) else v
            for k, v in values.items()}


def get_config(name: str, *, tiny: bool = False, **overrides: Any) -> Any:
    """The config of a model: the study's defaults (or ``tiny()``) with overrides applied.

    Args:
        name: model name or alias.
        tiny: start from the model's test-sized config.
        **overrides: config fields to replace; unknown fields raise :class:`ConfigError`.
    Returns:
        A frozen config dataclass instance.
    """
    key = canonical_name(name)
    cls = MODEL_SPECS[key].config_cls
    base = cls.tiny() if tiny else cls()
    return dataclasses.replace(base, **_coerce(cls, overrides, key))


def create_model(name: str, config: Any = None) -> Surrogate:
    """Build a surrogate by name (see :data:`MODEL_NAMES`, :data:`ALIASES`).

    Args:
        name: model name or alias; unknown names raise :class:`ConfigError` listing known ones.
        config: its config dataclass (default: the study's); a wrong type raises ConfigError.
    Returns:
        The surrogate (frozen dataclass, hashable: usable as a static jit argument).
    """
    key = canonical_name(name)
    spec = MODEL_SPECS[key]
    if config is None:
        config = spec.config_cls()
    if not isinstance(config, spec.config_cls):
        want, got = spec.config_cls.__name__, type(config).__name__
        raise ConfigError(f"model '{key}' needs a {want}, got {got}")
    cls = getattr(importlib.import_module(spec.module), spec.surrogate)
    return cls(name=key, config=config)


def config_to_dict(config: Any) -> dict:
    """JSON-ready dict of a config (tuples become lists)."""
    items = dataclasses.asdict(config).items()
    return {k: list(v) if isinstance(v, tuple) else v for k, v in items}


def config_from_dict(name: str, d: dict) -> Any:
    """Inverse of :func:`config_to_dict`; unknown keys raise :class:`ConfigError`.

    Missing keys take the defaults of the model's config class.
    """
    key = canonical_name(name)
    cls = MODEL_SPECS[key].config_cls
    return cls(**_coerce(cls, dict(d), key))


def count_params(params: Any) -> int:
    """Total number of scalar parameters in a pytree of arrays."""
    return int(sum(x.size for x in jax.tree_util.tree_leaves(params)))
