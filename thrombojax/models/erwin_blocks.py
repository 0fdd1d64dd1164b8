"""Erwin's transformer blocks: ball attention, the pre-norm block, and a level's block stack.

Split out of :mod:`thrombojax.models.erwin` (the U-Net, pooling and the surrogate), which
describes the model and its conventions. A ball of ``m`` leaves is a contiguous slice of ``m``
rows of the tree-ordered features, so every ball operation is a reshape (:func:`ball_view`).

``remat`` (``ErwinConfig.remat``): every block is rematerialised
(:func:`thrombojax.models.layers.remat_call`): the backward pass recomputes a block from its
input instead of storing its activations (the ``[B, H, m, m]`` attention logits and weights of
every ball, the SwiGLU hidden layers), for about one more forward pass of the blocks (peaks:
``benchmarks/train_step.py``).
"""

from __future__ import annotations

import math

import flax.linen as nn
import jax
import jax.numpy as jnp

from thrombojax.models.layers import RMSNorm, SwiGLU, remat_call

__all__ = ["MASKED", "dense", "ball_view", "masked_centres", "BallMSA", "ErwinBlock",
           "BlockPair", "Stage"]

MASKED = -1e9  # additive logit for padded keys (finite, so an all-padding ball stays finite)


def dense(features: int, name: str | None = None) -> nn.Dense:
    """Dense with the official init: truncated-normal (std 0.02) kernel, zero bias."""
    return nn.Dense(features, kernel_init=nn.initializers.truncated_normal(0.02), name=name)


def ball_view(a: jax.Array, m: int) -> jax.Array:
    """``[M, ...] -> [M / m, m, ...]`` contiguous balls of ``m`` leaves."""
    return a.reshape((a.shape[0] // m, m) + a.shape[1:])


def masked_centres(pos: jax.Array, valid: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Ball centres over real members. ``pos [B, m, 3]``, ``valid [B, m]`` -> ``[B, 1, 3]``, w."""
    w = valid[..., None].astype(pos.dtype)
    count = w.sum(axis=1, keepdims=True)
    masked = (pos * w).sum(axis=1, keepdims=True) / jnp.maximum(count, 1.0)
    centres = jnp.where(count > 0, masked, pos.mean(axis=1, keepdims=True))
    return centres, w


class BallMSA(nn.Module):
    """Ball multi-head self-attention with positional term and distance fall-off (eqs. 8-10).

    Attributes:
        dim: feature width C (divisible by ``num_heads``).
        num_heads: number of heads H.
        ball_size: leaves per ball m (divides the number of rows).
    """

    dim: int
    num_heads: int
    ball_size: int

    @nn.compact
    def __call__(self, x: jax.Array, pos: jax.Array, valid: jax.Array) -> jax.Array:
        """Args: x ``[M, C]``, pos ``[M, 3]``, valid ``[M]`` bool. Returns ``[M, C]``."""
        m, h = self.ball_size, self.num_heads
        e = self.dim // h
        xb, pb, vb = ball_view(x, m), ball_view(pos, m), ball_view(valid, m)
        centres, w = masked_centres(pb, vb)
        xb = xb + dense(self.dim, "pe_proj")((pb - centres) * w)
        qkv = dense(3 * self.dim, "qkv")(xb).reshape(xb.shape[:2] + (3, h, e))
        q, k, v = qkv[:, :, 0], qkv[:, :, 1], qkv[:, :, 2]  # [B, m, H, E]
        logits = jnp.einsum("bqhe,bkhe->bhqk", q, k) / math.sqrt(e)
        sigma = self.param(
            "sigma", lambda key: -1.0 + 0.01 * jax.random.normal(key, (h,), jnp.float32)
        )
        d2 = jnp.sum((pb[:, :, None, :] - pb[:, None, :, :]) ** 2, axis=-1)
        dist = jnp.sqrt(jnp.maximum(d2, 1e-12))  # [B, m, m]
        logits = logits + sigma[None, :, None, None] * dist[:, None]
        logits = jnp.where(vb[:, None, None, :], logits, MASKED)
        attn = jax.nn.softmax(logits, axis=-1)
        out = jnp.einsum("bhqk,bkhe->bqhe", attn, v).reshape(x.shape[0], self.dim)
        return dense(self.dim, "proj")(out)


class ErwinBlock(nn.Module):
    """Pre-norm transformer block: ``x + BallMSA(RMSNorm x)``, then ``x + SwiGLU(RMSNorm x)``."""

    dim: int
    num_heads: int
    ball_size: int
    mlp_ratio: int

    @nn.compact
    def __call__(self, x: jax.Array, pos: jax.Array, valid: jax.Array) -> jax.Array:
        """Args: x ``[M, C]``, pos ``[M, 3]``, valid ``[M]``. Returns ``[M, C]``."""
        x = x + BallMSA(self.dim, self.num_heads, self.ball_size, name="attn")(
            RMSNorm(name="norm1")(x), pos, valid
        )
        return x + SwiGLU(self.dim * self.mlp_ratio, name="mlp")(RMSNorm(name="norm2")(x))


def _call(block: ErwinBlock, remat: bool, x, pos, valid) -> jax.Array:
    """``block(x, pos, valid)``, rematerialised when ``remat``."""
    return remat_call(block, x, pos, valid) if remat else block(x, pos, valid)


class BlockPair(nn.Module):
    """Blocks ``2k`` (tree order) and ``2k + 1`` (rotated tree order when ``rotate``).

    Attributes:
        dim, num_heads, ball_size, mlp_ratio: the :class:`ErwinBlock` settings.
        rotate: run the second block in the rotated tree's order.
        remat: rematerialise both blocks (module docstring).
    """

    dim: int
    num_heads: int
    ball_size: int
    mlp_ratio: int
    rotate: bool
    remat: bool = False

    @nn.compact
    def __call__(self, x, pos, valid, rot, inv):
        """``x [M, C]``, ``pos [M, 3]``, ``valid [M]``; ``rot``/``inv`` ``[M]`` rotated order."""
        args = (self.dim, self.num_heads, self.ball_size, self.mlp_ratio)
        x = _call(ErwinBlock(*args, name="plain"), self.remat, x, pos, valid)
        second = ErwinBlock(*args, name="rot")
        if self.rotate:
            return _call(second, self.remat, x[rot], pos[rot], valid[rot])[inv], None
        return _call(second, self.remat, x, pos, valid), None


class Stage(nn.Module):
    """``depth`` blocks at one tree level; odd blocks run in the rotated tree's order.

    Pairs of blocks are an ``nn.scan`` (parameters stacked on a leading axis of length
    ``depth // 2``), so compile time does not grow with depth; an odd last block follows.

    Attributes:
        dim, depth, num_heads, ball_size, mlp_ratio: width, blocks and block settings.
        rotate: odd blocks in the rotated tree's order. remat: rematerialise every block.
    """

    dim: int
    depth: int
    num_heads: int
    ball_size: int
    mlp_ratio: int
    rotate: bool
    remat: bool = False

    @nn.compact
    def __call__(self, x, pos, valid, rot, inv):
        """``x [M, C]``, ``pos [M, 3]``, ``valid [M]``; ``rot``/``inv`` ``[M]`` rotated order."""
        args = (self.dim, self.num_heads, self.ball_size, self.mlp_ratio)
        if self.depth // 2:
            pairs = nn.scan(BlockPair, variable_axes={"params": 0}, split_rngs={"params": True},
                            in_axes=nn.broadcast, length=self.depth // 2)
            x, _ = pairs(*args, self.rotate, self.remat, name="pairs")(x, pos, valid, rot, inv)
        if self.depth % 2:
            x = _call(ErwinBlock(*args, name="last"), self.remat, x, pos, valid)
        return x
