"""Transolver (Wu et al. 2024) with Physics-Attention, fed the MPNN spatial embedding of Erwin.

The study took Transolver from NVIDIA PhysicsNeMo (itself from thuml/Transolver) and, since it
needs a spatial embedding on unstructured points, gave it Erwin's MPNN embedding. One sample:

    f   = [velocity, one_hot(type)]                                   [n, 5]
    emb = MPNNEmbedding(f, positions, radius graph)                    [n, C]
    x   = Dense-GELU-Dense([emb, f]) (width 2C then C)                 preprocess
    x  <- x + PhysicsAttention(LN(x));  x <- x + MLP(LN(x))            pre-norm blocks (x layers)
    out = Dense(LN(x))                                                 [n, 3]

Physics-Attention (paper eqs. 2-5), per head h with ``M`` slices:

    w_nh  = softmax_m(W_s (W_x x_n)_h / tau_h) * mask_n                soft slice assignment
    z_hm  = sum_n w_nhm (W_f x_n)_h / (sum_n w_nhm + eps)              slice tokens
    z'_h  = softmax(Q z_h (K z_h)^T / sqrt(d)) V z_h                   attention among slices
    y_n   = W_o concat_h(sum_m w_nhm z'_hm)                            deslice + projection

Padded nodes get zero slice weight, so they never reach a slice token and cannot change any real
node's output; the MPNN graph excludes them as well.

Conventions (references disagree; choices):

* Temperature ``tau_h`` is a learnable per-head scalar initialised at 0.5 and clamped to
  [0.5, 5] (PhysicsNeMo; thuml's irregular-mesh code does not clamp).
* Slice-token normaliser ``eps = 1e-2`` added to the weight sum (PhysicsNeMo; thuml uses 1e-5).
* Q, K, V are bias-free projections of width ``d = C / heads`` shared across heads, as both.
* Dropout (``config.dropout``) on the slice attention weights and after the output projection
  (thuml; PhysicsNeMo's SDPA path drops only after the projection). Active only with
  ``train=True``, drawing from the ``"dropout"`` RNG stream.
* GELU exact (erf); LayerNorm eps 1e-5; Dense kernels truncated-normal(0.02) with zero bias
  (Transolver's ``_init_weights``), the slice projection orthogonal; the MPNN embedding keeps
  the default initialisation of :mod:`thrombojax.models.layers`.
* Graph: radius graph with self loops (``torch_cluster.radius_graph(loop=True)`` in Erwin).

``config.remat``: every block is rematerialised (:func:`thrombojax.models.layers.remat_call`):
the backward pass recomputes a block from its input instead of storing its activations (the
``[n, H, M]`` slice weights, the ``[n, mlp_ratio C]`` MLP hidden layer), for about one more
forward pass of the blocks (peaks: ``benchmarks/train_step.py``). In training with dropout each
block then draws one key from the ``"dropout"`` stream and derives its masks from it, so the
recomputation reuses the forward pass's masks; these masks differ from those of the default
path (same distribution), so a run with ``remat`` is not bit-identical to one without.
"""

from __future__ import annotations

import dataclasses
import functools

import flax.linen as nn
import jax
import jax.numpy as jnp

from thrombojax.graph.neighbors import NeighborList
from thrombojax.models.layers import MLP, MPNNEmbedding, gelu, layer_norm, remat_call
from thrombojax.models.registry import FlaxSurrogate, TransolverConfig
from thrombojax.types import ModelInput

__all__ = ["PhysicsAttention", "TransolverBlock", "Transolver", "TransolverSurrogate"]

OUTPUT_DIM: int = 3
TEMPERATURE_INIT: float = 0.5
TEMPERATURE_RANGE: tuple[float, float] = (0.5, 5.0)
SLICE_NORM_EPS: float = 1e-2

_INIT = nn.initializers.truncated_normal(0.02)
_dense = functools.partial(nn.Dense, kernel_init=_INIT)


class PhysicsAttention(nn.Module):
    """Physics-Attention on irregular points (one sample).

    Attributes:
        heads: number of heads ``H``; the head width is ``C // H``.
        slices: number of slices ``M`` per head.
        dropout: dropout rate (attention weights and output), used when ``train``.
    """

    heads: int
    slices: int
    dropout: float = 0.0

    @nn.compact
    def __call__(self, x: jax.Array, mask: jax.Array, key: jax.Array | None = None, *,
                 train: bool = False) -> jax.Array:
        """Args: x ``[n, C]`` tokens; mask ``[n]`` bool real tokens; key: the dropout key
        (default: drawn from the ``"dropout"`` RNG stream). Returns: ``[n, C]``."""
        n, c = x.shape
        keys = (None, None) if key is None else tuple(jax.random.split(key))
        h, d = self.heads, c // self.heads
        fx = _dense(h * d, name="in_project_fx")(x).reshape(n, h, d)
        xs = _dense(h * d, name="in_project_x")(x).reshape(n, h, d)
        logits = nn.Dense(
            self.slices, kernel_init=nn.initializers.orthogonal(), name="in_project_slice"
        )(xs)  # [n, H, M]
        temperature = self.param(
            "temperature", nn.initializers.constant(TEMPERATURE_INIT), (h,), jnp.float32
        )
        tau = jnp.clip(temperature, *TEMPERATURE_RANGE)[None, :, None]
        weights = jax.nn.softmax(logits / tau, axis=-1)
        weights = jnp.where(mask[:, None, None], weights, 0.0)  # padded tokens: no slice weight
        norm = jnp.sum(weights, axis=0) + SLICE_NORM_EPS  # [H, M]
        tokens = jnp.einsum("nhm,nhd->hmd", weights, fx) / norm[..., None]  # [H, M, d]

        qkv = nn.Dense(3 * d, use_bias=False, kernel_init=_INIT, name="qkv")(tokens)
        q, k, v = jnp.split(qkv, 3, axis=-1)
        attn = jax.nn.softmax(jnp.einsum("hmd,hkd->hmk", q, k) * d**-0.5, axis=-1)
        attn = nn.Dropout(self.dropout, name="attn_dropout")(attn, not train, keys[0])
        out_tokens = jnp.einsum("hmk,hkd->hmd", attn, v)

        y = jnp.einsum("nhm,hmd->nhd", weights, out_tokens).reshape(n, h * d)
        y = _dense(c, name="out")(y)
        return nn.Dropout(self.dropout, name="out_dropout")(y, not train, keys[1])


class TransolverBlock(nn.Module):
    """Pre-norm block ``x += Attn(LN(x)); x += MLP(LN(x))``.

    Attributes:
        heads, slices, dropout: Physics-Attention settings.
        mlp_ratio: hidden width factor of the block MLP (Dense-GELU-Dense).
    """

    heads: int
    slices: int
    dropout: float
    mlp_ratio: int

    @nn.compact
    def __call__(self, x: jax.Array, mask: jax.Array, key: jax.Array | None = None, *,
                 train: bool = False) -> jax.Array:
        """Args: x ``[n, C]``; mask ``[n]``; key: the dropout key (default: drawn from the
        ``"dropout"`` RNG stream). Returns: ``[n, C]``."""
        c = x.shape[-1]
        attn = PhysicsAttention(self.heads, self.slices, self.dropout, name="attention")
        x = x + attn(layer_norm("ln_1")(x), mask, key, train=train)
        mlp = MLP((c * self.mlp_ratio, c), activation=gelu, kernel_init=_INIT, name="mlp")
        return x + mlp(layer_norm("ln_2")(x))


class Transolver(nn.Module):
    """The Transolver network on one sample.

    Attributes:
        config: :class:`~thrombojax.models.registry.TransolverConfig`.
        split_messages: the embedding's split message layer (``MPNNEmbedding.split``; False:
            the plain concatenation, for ``benchmarks/train_step.py``).
    """

    config: TransolverConfig
    split_messages: bool = True

    @nn.compact
    def __call__(
        self, inputs: ModelInput, graph: NeighborList, *, train: bool = False
    ) -> jax.Array:
        """Predict the normalised acceleration.

        Args:
            inputs: positions, velocity ``[n_nodes, 3]``, node types and mask ``[n_nodes]``.
            graph: radius graph (with self loops) of ``inputs.positions``.
            train: enable dropout (needs the ``"dropout"`` RNG).
        Returns:
            ``[n_nodes, 3]``.
        """
        cfg = self.config
        feats = inputs.node_features
        positions = jax.lax.stop_gradient(inputs.positions)
        emb = MPNNEmbedding(cfg.hidden, cfg.mp_steps, split=self.split_messages,
                            name="embedding")(
            feats, positions, graph.indices
        )
        x = MLP((2 * cfg.hidden, cfg.hidden), activation=gelu, kernel_init=_INIT,
                name="preprocess")(jnp.concatenate([emb, feats], axis=-1))
        for i in range(cfg.layers):
            block = TransolverBlock(cfg.heads, cfg.slices, cfg.dropout, cfg.mlp_ratio,
                                    name=f"block_{i}")
            if not cfg.remat:
                x = block(x, inputs.mask, train=train)
            elif train and cfg.dropout > 0.0:  # the recomputation needs the forward's masks
                x = remat_call(block, x, inputs.mask, self.make_rng("dropout"), train=True)
            else:
                x = remat_call(block, x, inputs.mask, train=train)
        return _dense(OUTPUT_DIM, name="head")(layer_norm("ln_out")(x))


@dataclasses.dataclass(frozen=True)
class TransolverSurrogate(FlaxSurrogate):
    """Transolver behind the common surrogate contract (radius graph with self loops)."""

    module_cls = Transolver
    self_loops = True
