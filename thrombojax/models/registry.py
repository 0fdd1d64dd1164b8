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
from thrombojax.types import ModelInput, TargetStats

__all__ = [
    "MeshGraphNetConfig", "TransolverConfig", "ErwinConfig", "ConstantVelocityConfig",
    "Surrogate", "FlaxSurrogate", "ConstantVelocity", "EmptyGraph", "ModelSpec",
    "MODEL_SPECS", "MODEL_NAMES", "ALIASES", "canonical_name", "get_config", "create_model",
    "config_to_dict", "config_from_dict", "count_params", "identity_stats",
]  # fmt: skip


# ---- configs ------------------------------------------------------------------------------


def _check_positive(config: Any, *names: str) -> None:
    """Raise :class:`ConfigError` unless every named field of ``config`` is > 0."""
    for name in names:
        value = getattr(config, name)
        if not value > 0:
            raise ConfigError(f"{type(config).__name__}.{name} must be > 0, got {value!r}")


@dataclasses.dataclass(frozen=True)
class MeshGraphNetConfig:
    """MeshGraphNet (Pfaff et al. 2021, PhysicsNeMo's variant). Study: hidden 64, 15 blocks.

    Attributes:
        hidden: width of every latent and every MLP hidden layer.
        processor_size: number of unshared message-passing blocks.
        mlp_layers: hidden layers per MLP (PhysicsNeMo ``num_layers_*`` default 2).
        radius: radius of the world-edge graph in scaled coordinates.
        max_neighbors: neighbour cap per node (torch_cluster's default 32).
        remat: rematerialise the processor MLPs in the backward pass (less memory, more compute).
    """

    hidden: int = 64
    processor_size: int = 15
    mlp_layers: int = 2
    radius: float = 0.56
    max_neighbors: int = 32
    remat: bool = False

    def __post_init__(self) -> None:
        _check_positive(self, "hidden", "processor_size", "mlp_layers", "radius", "max_neighbors")

    @classmethod
    def tiny(cls) -> MeshGraphNetConfig:
        """A few-thousand-parameter config for tests."""
        return cls(hidden=8, processor_size=2, mlp_layers=1, max_neighbors=8)


@dataclasses.dataclass(frozen=True)
class TransolverConfig:
    """Transolver (Wu et al. 2024, PhysicsNeMo's) with Erwin's MPNN embedding as spatial input.

    The study prints dropout 0.576, the same digits as its radius; that looks like a copy slip in
    the thesis table, but it is kept as the default (override ``dropout`` to change it).

    Attributes:
        hidden: token width; must be divisible by ``heads``.
        heads: attention heads (head width ``hidden // heads``).
        layers: Transolver blocks.
        slices: physics slices M per head.
        dropout: dropout on slice attention weights and on the attention output projection.
        mlp_ratio: block MLP width factor (PhysicsNeMo default 4).
        mp_steps: message-passing steps of the MPNN embedding (Erwin's default 3).
        radius, max_neighbors: radius graph of the MPNN embedding (self loops included).
    """

    hidden: int = 64
    heads: int = 16
    layers: int = 5
    slices: int = 24
    dropout: float = 0.576
    mlp_ratio: int = 4
    mp_steps: int = 3
    radius: float = 0.576
    max_neighbors: int = 32

    def __post_init__(self) -> None:
        _check_positive(self, "hidden", "heads", "layers", "slices", "mlp_ratio", "radius",
                        "max_neighbors")
        if self.hidden % self.heads:
            raise ConfigError(f"transolver: hidden {self.hidden} % heads {self.heads} != 0")
        if not 0.0 <= self.dropout < 1.0:
            raise ConfigError(f"transolver: dropout must be in [0, 1), got {self.dropout}")

    @classmethod
    def tiny(cls) -> TransolverConfig:
        """A small config for tests (dropout kept non-zero so the train path is exercised)."""
        return cls(hidden=8, heads=2, layers=2, slices=4, dropout=0.1, mlp_ratio=2, mp_steps=1,
                   max_neighbors=8)


@dataclasses.dataclass(frozen=True)
class ErwinConfig:
    """Erwin (Zhdanov et al. 2025, official code). Study hyper-parameters as defaults.

    ``enc_*`` and ``ball_sizes`` have one entry per encoder level plus the bottleneck (the last
    entry); ``dec_*`` and ``strides`` one per encoder level.

    Attributes:
        hidden: width at the finest level.
        enc_heads, enc_depths: heads and blocks per encoder level (last: bottleneck).
        dec_heads, dec_depths: heads and blocks per decoder level.
        strides: pooling stride between levels.
        ball_sizes: leaves per attention ball per level.
        mlp_ratio: SwiGLU width factor.
        rotate: angle (degrees) of the rotated tree used every other block (0: off).
        widen: widths grow with coarsening, ``hidden * prod(strides[:l])`` at level ``l``
            (32, 64, 128, 256: the official README and pre-May-2025 int ``c_hidden``);
            False keeps ``hidden`` at every level (the thesis prints one hidden size).
        mp_steps: message-passing steps of the MPNN embedding.
        radius, max_neighbors: radius graph of the MPNN embedding (self loops included).
    """

    hidden: int = 32
    enc_heads: tuple[int, ...] = (4, 4, 4, 4)
    enc_depths: tuple[int, ...] = (8, 10, 12, 14)
    dec_heads: tuple[int, ...] = (4, 4, 4)
    dec_depths: tuple[int, ...] = (4, 4, 4)
    strides: tuple[int, ...] = (2, 2, 2)
    ball_sizes: tuple[int, ...] = (128, 128, 128, 128)
    mlp_ratio: int = 4
    rotate: float = 45.0
    widen: bool = True
    mp_steps: int = 3
    radius: float = 0.766
    max_neighbors: int = 32

    @classmethod
    def tiny(cls) -> ErwinConfig:
        """One pooling level, two blocks per level, balls of 8: for tests."""
        return cls(hidden=8, enc_heads=(2, 2), enc_depths=(2, 2), dec_heads=(2,),
                   dec_depths=(2,), strides=(2,), ball_sizes=(8, 8), mlp_ratio=2, mp_steps=1,
                   max_neighbors=8)


@dataclasses.dataclass(frozen=True)
class ConstantVelocityConfig:
    """The constant-velocity baseline has no hyper-parameters; the graph fields are unused."""

    radius: float = 0.0
    max_neighbors: int = 32

    @classmethod
    def tiny(cls) -> ConstantVelocityConfig:
        return cls()


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
    """

    name: str
    config: Any
    module_cls: ClassVar[type[nn.Module]]
    self_loops: ClassVar[bool] = False

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
        """Normalised acceleration ``[n_nodes, 3]``; ``rng`` is needed to train with dropout."""
        if train and rng is None and getattr(self.config, "dropout", 0.0) > 0.0:
            raise ConfigError(f"model '{self.name}': apply(train=True) uses dropout and needs rng")
        rngs = {} if rng is None else {"dropout": rng}
        return self.module.apply(params, inputs, graph, train=train, rngs=rngs)


@functools.partial(jax.jit, static_argnums=0)
def _init_flax(model: FlaxSurrogate, rng: jax.Array, inputs: ModelInput, graph: Any) -> dict:
    params_rng, dropout_rng = jax.random.split(rng)
    rngs = {"params": params_rng, "dropout": dropout_rng}
    return dict(model.module.init(rngs, inputs, graph, train=False))


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
