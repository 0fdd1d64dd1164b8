"""Building blocks shared by the surrogates: MLP, RMSNorm, SwiGLU and the MPNN embedding.

Conventions (chosen where the reference implementations disagree; every model inherits them):

* **GELU** is the exact (erf) form, :func:`gelu`, as ``torch.nn.GELU()`` in the official Erwin
  and Transolver code; Flax's ``nn.gelu`` defaults to the tanh approximation, which we do not use.
* **LayerNorm epsilon** is ``1e-5`` (PyTorch's default, used by PhysicsNeMo, Erwin and Transolver;
  Flax's default is ``1e-6``).
* **RMSNorm epsilon** defaults to float32 machine epsilon (``1.19e-7``), which is what
  ``torch.nn.RMSNorm(eps=None)`` in the official Erwin code uses.
* **Initialisation**: zero biases; weights from ``kernel_init`` (default :data:`DEFAULT_INIT`,
  Flax's LeCun normal). The PyTorch references use Kaiming-uniform (``nn.Linear`` default) or
  truncated-normal(0.02) (Erwin, Transolver); models pass their choice as ``kernel_init``.
* **Graphs** are dense, fixed-capacity neighbour lists ``[n_nodes, max_neighbors]`` with the
  sentinel index ``n_nodes`` in empty slots (:class:`thrombojax.graph.neighbors.NeighborList`).
  Row ``i`` lists the *senders* ``j`` of the edges ``j -> i``; node ``i`` is the receiver.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp

__all__ = [
    "DEFAULT_INIT",
    "LAYER_NORM_EPS",
    "RMS_NORM_EPS",
    "gelu",
    "layer_norm",
    "MLP",
    "mlp_tail",
    "remat_call",
    "SplitDense",
    "RMSNorm",
    "SwiGLU",
    "MPNNEmbedding",
    "gather_neighbors",
    "neighbor_mask",
]

Initializer = Callable[..., jax.Array]

DEFAULT_INIT: Initializer = nn.initializers.lecun_normal()
"""Default Dense kernel initialiser (Flax's)."""
LAYER_NORM_EPS: float = 1e-5
"""LayerNorm epsilon of every model (PyTorch default)."""
RMS_NORM_EPS: float = float(jnp.finfo(jnp.float32).eps)
"""RMSNorm epsilon (``torch.nn.RMSNorm(eps=None)`` for float32 inputs)."""


def gelu(x: jax.Array) -> jax.Array:
    """Exact GELU, ``x * Phi(x)`` with the Gaussian CDF (not the tanh approximation)."""
    return jax.nn.gelu(x, approximate=False)


def layer_norm(name: str | None = None) -> nn.LayerNorm:
    """A LayerNorm with the library's epsilon (``1e-5``) and learnable scale and bias."""
    return nn.LayerNorm(epsilon=LAYER_NORM_EPS, name=name)


class MLP(nn.Module):
    """Multi-layer perceptron: ``Dense -> act -> ... -> Dense`` and an optional output LayerNorm.

    The activation follows every layer but the last. With ``layer_norm=True`` a LayerNorm is
    applied to the output, as in MeshGraphNet (PhysicsNeMo ``MeshGraphMLP``, DeepMind
    ``meshgraphnets``): ``LN(W_L act(... act(W_1 x)))``.

    Attributes:
        features: output width of each Dense layer; the last entry is the output width.
        activation: element-wise non-linearity between layers.
        layer_norm: apply LayerNorm (eps ``1e-5``) to the output.
        kernel_init: Dense kernel initialiser.
    """

    features: Sequence[int]
    activation: Callable[[jax.Array], jax.Array] = gelu
    layer_norm: bool = False
    kernel_init: Initializer = DEFAULT_INIT

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        """Args: x: ``[..., d_in]``. Returns: ``[..., features[-1]]``."""
        x = nn.Dense(self.features[0], kernel_init=self.kernel_init, name="dense_0")(x)
        return mlp_tail(x, self.features, self.activation, norm=self.layer_norm,
                        kernel_init=self.kernel_init)


def mlp_tail(
    x: jax.Array,
    features: Sequence[int],
    activation: Callable[[jax.Array], jax.Array],
    *,
    norm: bool,
    kernel_init: Initializer = DEFAULT_INIT,
) -> jax.Array:
    """The layers of an :class:`MLP` after its first Dense, on that Dense's output ``x``.

    ``act -> dense_1 -> ... -> dense_{L}`` and the optional LayerNorm ``norm``, created in the
    calling module (call it inside a ``@nn.compact`` method), so a module that computes
    ``dense_0`` its own way (:class:`SplitDense`) keeps the parameter tree of :class:`MLP`.
    """
    for i, width in enumerate(features[1:], 1):
        x = nn.Dense(width, kernel_init=kernel_init, name=f"dense_{i}")(activation(x))
    return layer_norm("norm")(x) if norm else x


def remat_call(module: nn.Module, *args: jax.Array, **static: Any) -> jax.Array:
    """``module(*args)``, its activations recomputed in the backward pass instead of stored.

    What ``flax.linen.remat`` promises, made to hold on the CPU: XLA's CPU pipeline drops the
    optimisation barriers of ``jax.checkpoint`` and common-subexpression elimination then merges
    the backward recomputation with the forward pass, so every activation is stored anyway (the
    compiled temporaries do not shrink). Here the backward pass recomputes from the stored
    inputs with the parameters shifted by ``0 * ct[0]``, a data dependence on the incoming
    cotangent that no pass can merge away (exact: adding 0 changes no value). Call it inside a
    ``@nn.compact`` method with an unbound, named submodule; parameters and outputs are those of
    ``module(*args)``, gradients equal to rounding (``tests/test_mgn_fast.py``,
    ``tests/test_remat.py``).

    The recomputation sees only the parameters and ``args``: a module that draws random numbers
    (dropout) must take its key as one of ``args`` (as :class:`~thrombojax.models.transolver.
    TransolverBlock` does), or the backward pass would lack the forward pass's masks.

    Args:
        module: a submodule (``name=`` set) returning one array.
        *args: its array arguments (integer, boolean and key arrays get no gradient).
        **static: non-array keyword arguments of the call (``train=True``), passed unchanged.
    """
    parent = module.parent
    if isinstance(parent, nn.Module) and parent.is_initializing():
        # the same parameters (tests/test_remat.py); no lifted transform for the init to cross
        return module(*args, **static)
    definition = module.clone(parent=None)

    def pure(params, *a):
        return definition.apply({"params": params}, *a, **static)

    def fwd(mdl, *a):
        return mdl(*a, **static), (mdl.variables["params"], a)

    def bwd(residuals, ct):
        params, a = residuals
        zero = 0.0 * ct.reshape(-1)[0]
        params = jax.tree.map(lambda p: p + zero.astype(p.dtype), params)
        _, vjp = jax.vjp(pure, params, *a)
        params_t, *args_t = vjp(ct)
        return ({"params": params_t}, *args_t)

    return nn.custom_vjp(lambda mdl, *a: mdl(*a, **static), fwd, bwd)(module, *args)


class SplitDense(nn.Module):
    """``nn.Dense`` of a concatenation ``[x_1, ..., x_P]``, applied part by part.

    ``W [x_1, ..., x_P] + b = W_1 x_1 + ... + W_P x_P + b`` with ``W_p`` the row block of the
    one kernel that multiplies part ``p``. The parameters are exactly those ``nn.Dense`` would
    create for the concatenated input (``kernel [sum d_p, features]``, ``bias [features]``, same
    names, shapes and initialisation), so a checkpoint of one loads into the other. Returning the
    projections separately lets the caller project per *node* and gather per *edge* instead of
    concatenating per-edge copies (the factorised first layer of an edge MLP).

    Attributes:
        features: output width.
        kernel_init: kernel initialiser (of the whole ``[sum d_p, features]`` kernel).
        bias_part: the part whose projection carries ``b`` (pick a per-node part: fewer adds).
    """

    features: int
    kernel_init: Initializer = DEFAULT_INIT
    bias_part: int = 0

    @nn.compact
    def __call__(self, *parts: jax.Array) -> tuple[jax.Array, ...]:
        """Args: parts ``[..., d_p]`` (any leading shapes). Returns: ``x_p W_p`` per part, ``b``
        added to part ``bias_part``."""
        sizes = [x.shape[-1] for x in parts]
        kernel = self.param("kernel", self.kernel_init, (sum(sizes), self.features), jnp.float32)
        bias = self.param("bias", nn.initializers.zeros_init(), (self.features,), jnp.float32)
        starts = [sum(sizes[:p]) for p in range(len(parts))]
        out = [x @ kernel[a:a + d] for x, a, d in zip(parts, starts, sizes, strict=True)]
        out[self.bias_part] = out[self.bias_part] + bias
        return tuple(out)


class RMSNorm(nn.Module):
    """Root-mean-square normalisation with a learnable per-feature scale (no bias, no centring).

    ``y = x / sqrt(mean(x**2) + eps) * scale`` (Zhang and Sennrich 2019), as in Erwin.

    Attributes:
        epsilon: added to the mean square; default float32 machine epsilon as in
            ``torch.nn.RMSNorm(eps=None)``.
    """

    epsilon: float = RMS_NORM_EPS

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        """Args: x: ``[..., d]``. Returns: ``[..., d]``."""
        scale = self.param("scale", nn.initializers.ones, (x.shape[-1],), jnp.float32)
        ms = jnp.mean(jnp.square(x), axis=-1, keepdims=True)
        return x * jax.lax.rsqrt(ms + self.epsilon) * scale


class SwiGLU(nn.Module):
    """Gated feed-forward block ``W_3 (SiLU(W_1 x) * W_2 x)`` (Shazeer 2020), as in Erwin.

    All three projections have biases (as ``nn.Linear`` in the official Erwin code).

    Attributes:
        hidden: width of the gated hidden layer (``mlp_ratio * d`` in Erwin).
        kernel_init: Dense kernel initialiser.
    """

    hidden: int
    kernel_init: Initializer = DEFAULT_INIT

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        """Args: x: ``[..., d]``. Returns: ``[..., d]``."""
        dense = functools.partial(nn.Dense, kernel_init=self.kernel_init)
        gate = jax.nn.silu(dense(self.hidden, name="w1")(x))
        value = dense(self.hidden, name="w2")(x)
        return dense(x.shape[-1], name="w3")(gate * value)


def neighbor_mask(neighbors: jax.Array) -> jax.Array:
    """Valid slots of a dense neighbour list.

    Args:
        neighbors: ``[n_nodes, k]`` int sender indices, sentinel ``n_nodes`` in empty slots.
    Returns:
        ``[n_nodes, k]`` bool, True where the slot holds a real neighbour.
    """
    n_nodes = neighbors.shape[0]
    return (neighbors >= 0) & (neighbors < n_nodes)


def gather_neighbors(x: jax.Array, neighbors: jax.Array) -> jax.Array:
    """Gather per-node values at the neighbour slots; sentinel slots read zeros.

    Args:
        x: ``[n_nodes, ...]`` per-node values.
        neighbors: ``[n_nodes, k]`` int sender indices, sentinel ``n_nodes`` in empty slots.
    Returns:
        ``[n_nodes, k, ...]``, ``x[neighbors]`` with zeros where the slot is empty.
    """
    padded = jnp.concatenate([x, jnp.zeros((1,) + x.shape[1:], x.dtype)], axis=0)
    return padded[jnp.clip(neighbors, 0, x.shape[0])]


class MPNNEmbedding(nn.Module):
    """Learned spatial embedding: a linear projection followed by message passing (Erwin's).

    Follows ``ErwinEmbedding``/``MPNN`` of the official Erwin code (Zhdanov et al. 2025), which
    the study also used as Transolver's spatial embedding. With ``h = W_in f`` and for each of
    ``mp_steps`` unshared steps, for the edges ``j -> i`` of the radius graph:

        m_ij = LN(GELU(W_m [h_j, h_i, x_j - x_i]))       message (source j, destination i)
        m_i  = mean_{j in N(i)} m_ij                      mean over valid neighbours (0 if none)
        h_i <- h_i + LN(W_u [h_i, m_i])                   post-norm residual update

    The relative position ``x_j - x_i`` (source minus destination) is the only geometric input,
    so the embedding is translation invariant. Whether ``i`` is its own neighbour is decided by
    the graph (Erwin builds it with ``loop=True``). Padded nodes must have no neighbours and be
    nobody's neighbour (as :func:`thrombojax.graph.neighbors.radius_graph` guarantees with a mask),
    so they never influence real nodes.

    Attributes:
        dim: embedding width.
        mp_steps: message-passing steps (Erwin's default 3); 0 gives the linear projection only.
        kernel_init: Dense kernel initialiser.
        split: apply the message layer as :class:`SplitDense` (``W_s h`` and ``W_d h`` once per
            node, gathered and broadcast to the ``[N, K]`` slots, plus ``W_x (x_j - x_i)``)
            instead of one Dense on the ``[N, K, 2 dim + 3]`` concatenation; same parameters,
            same result (``tests/test_layers.py``). False is the plain form, kept for the tests
            and ``benchmarks/train_step.py``.
    """

    dim: int
    mp_steps: int = 3
    kernel_init: Initializer = DEFAULT_INIT
    split: bool = True

    @nn.compact
    def __call__(
        self, features: jax.Array, positions: jax.Array, neighbors: jax.Array
    ) -> jax.Array:
        """Embed node features with their neighbourhoods.

        Args:
            features: ``[n_nodes, f]`` node features.
            positions: ``[n_nodes, 3]`` positions (scaled coordinates).
            neighbors: ``[n_nodes, k]`` int sender indices, sentinel ``n_nodes`` in empty slots.
        Returns:
            ``[n_nodes, dim]`` embeddings.
        """
        dense = functools.partial(nn.Dense, self.dim, kernel_init=self.kernel_init)
        h = dense(name="embed")(features)
        if self.mp_steps == 0:
            return h
        valid = neighbor_mask(neighbors)[..., None]  # [N, K, 1]
        rel = gather_neighbors(positions, neighbors) - positions[:, None, :]  # x_j - x_i
        rel = jnp.where(valid, rel, 0.0)
        count = jnp.maximum(jnp.sum(valid, axis=1), 1).astype(h.dtype)  # [N, 1]
        for step in range(self.mp_steps):
            if self.split:  # project per node, then gather: no [N, K, 2 dim + 3] concatenation
                message = SplitDense(self.dim, self.kernel_init, bias_part=1,
                                     name=f"message_{step}")
                p_src, p_dst, p_rel = message(h, h, rel)
                msg = gather_neighbors(p_src, neighbors) + p_dst[:, None, :] + p_rel
            else:
                h_src = gather_neighbors(h, neighbors)  # [N, K, dim]
                h_dst = jnp.broadcast_to(h[:, None, :], h_src.shape)
                msg = dense(name=f"message_{step}")(jnp.concatenate([h_src, h_dst, rel], -1))
            msg = layer_norm(f"message_norm_{step}")(gelu(msg))
            agg = jnp.sum(jnp.where(valid, msg, 0.0), axis=1) / count
            upd = dense(name=f"update_{step}")(jnp.concatenate([h, agg], axis=-1))
            h = h + layer_norm(f"update_norm_{step}")(upd)
        return h
