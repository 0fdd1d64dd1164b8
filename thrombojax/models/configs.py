"""The config dataclasses of the surrogates: frozen, architecture only, study defaults.

Re-exported by :mod:`thrombojax.models.registry` (the registry maps model names to these classes);
import them from either. Defaults are the study's architecture hyper-parameters; the study's
batch sizes and learning rates are training settings (:mod:`thrombojax.study`). ``tiny()`` gives
a test-sized config of each.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from thrombojax.errors import ConfigError

__all__ = ["MeshGraphNetConfig", "TransolverConfig", "ErwinConfig", "ConstantVelocityConfig"]


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
        remat: rematerialise the processor MLPs in the backward pass (on by default: the
            training step's compiled peak falls to 0.15x, 24.9 -> 3.7 GB at the study's
            ClotEntry batch, 8 x 2,048 nodes, and the step measured no slower on the CPU,
            ``docs/performance.md``; same outputs and gradients to rounding).
    """

    hidden: int = 64
    processor_size: int = 15
    mlp_layers: int = 2
    radius: float = 0.56
    max_neighbors: int = 32
    remat: bool = True

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
        remat: rematerialise the pre-norm blocks in the backward pass (less memory, more
            compute; :func:`thrombojax.models.layers.remat_call`).
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
    remat: bool = False

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
        remat: rematerialise the encoder and decoder blocks in the backward pass (less memory,
            more compute; :func:`thrombojax.models.layers.remat_call`).
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
    remat: bool = False

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
