"""Physics guards of a rollout step: containment in the rigid vessel and clot coherence.

Pure, jittable and vmappable functions on one frame; each returns the corrected positions and
how far it moved every node (``correction [N]``, 0 for nodes it left alone), so a rollout can
record per step how much the guards had to fix (a large correction means the model is wrong).

* :func:`contain`: clot nodes that crossed the rigid wall (signed distance beyond the wall's
  slack, not past an open end; see :mod:`thrombojax.simulator.wall`) are put back on the inner
  side, at their nearest wall point moved by ``margin`` along the inward normal.
* :func:`coherence`: shape matching (Mueller et al. 2005, "Meshless deformations based on shape
  matching"): the best rigid fit of the rest shape ``x_ref`` to the current clot (centroids and
  the rotation of the polar decomposition of ``sum (x - c)(x_ref - c_ref)^T``, by SVD with the
  reflection removed), and each node is pulled by ``stiffness`` toward that rigid copy for the
  part of its deviation beyond ``tolerance``. With ``max_stretch`` the copy may also deform
  (Mueller et al.'s linear deformation mode): the best affine fit's stretch, made
  volume-preserving and with every principal stretch limited to ``[1 / max_stretch,
  max_stretch]``, so a clot that shortens and widens as it leaves the vessel is not pulled back
  to its shape inside it.
* :func:`relax_edges`: edge-length relaxation on ``clot_cells`` edges: edges stretched or
  compressed beyond ``max_strain`` are brought back to the limit (Jacobi iterations, both ends
  move equally, moves of a node averaged over its violated edges).

The wall is built on the host with :func:`wall_from_simulation` (re-exported here).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.simulator.wall import Wall, WallQuery, nearest_wall_point, safe_norm
from thrombojax.simulator.wall_build import wall_from_simulation

__all__ = [
    "Wall",
    "WallQuery",
    "wall_from_simulation",
    "nearest_wall_point",
    "contain",
    "coherence",
    "relax_edges",
    "cell_edges",
]


def contain(
    x: jax.Array, movable_mask: jax.Array, wall: Wall, *, margin: float, tol: float = 0.0
) -> tuple[jax.Array, jax.Array]:
    """Put movable nodes that crossed the wall back inside. Jittable, vmappable.

    A node is outside when its signed wall distance exceeds ``slack + tol`` (slack: the outward
    bulge of the smooth wall beyond the nearest triangle, 0 for a node wall) and it is not past
    an open end. It moves to its nearest wall point plus ``margin`` along the inward normal;
    every other node keeps its position exactly.

    Args:
        x: ``[N, 3]`` positions (the wall's coordinates).
        movable_mask: ``[N]`` bool, nodes that may be moved (real clot nodes).
        wall: the :class:`Wall`.
        margin: distance inside the wall where a corrected node lands (>= 0).
        tol: extra signed distance tolerated before a node counts as outside (>= 0).
    Returns:
        ``(x_new [N, 3], correction [N])``: corrected positions and the distance each node moved.
    """
    q = nearest_wall_point(x, wall)
    out = movable_mask & (q.signed > q.slack + tol) & ~q.past_end
    target = q.point + margin * q.normal
    x_new = jnp.where(out[:, None], target, x)
    correction = jnp.where(out, safe_norm(target - x), 0.0)
    return x_new, correction


def _centroids(x, x_ref, w):
    """The weighted centroids ``c`` of ``x`` and ``c_ref`` of ``x_ref``."""
    total = jnp.maximum(jnp.sum(w), 1.0)
    return (jnp.sum(w[:, None] * x, axis=0) / total,
            jnp.sum(w[:, None] * x_ref, axis=0) / total)


def _proper(u, vt):
    """``[3]`` signs that make ``u @ diag(signs) @ vt`` a rotation (the reflection removed)."""
    d = jnp.sign(jnp.linalg.det(u @ vt))
    return jnp.ones(3, u.dtype).at[2].set(jnp.where(d == 0, 1.0, d))


def _rigid_rotation(x, x_ref, w, c, c_ref):
    """The rotation ``R`` minimising ``sum w |R (x_ref - c_ref) + c - x|^2``."""
    p, q = (x - c) * w[:, None], (x_ref - c_ref) * w[:, None]
    u, _, vt = jnp.linalg.svd(p.T @ q)  # [3, 3] sum_i p_i q_i^T
    return (u * _proper(u, vt)) @ vt


def _bounded_affine(x, x_ref, w, c, c_ref, max_stretch):
    """``[3, 3]`` map ``R S``: the rotation ``R`` and stretch ``S`` of the polar decomposition of
    the least-squares affine fit ``A = A_pq A_qq^-1`` of the rest shape onto the clot (Mueller
    et al. 2005, section 4.2), with ``S``'s principal stretches scaled to keep the volume and
    limited to ``[1 / max_stretch, max_stretch]``."""
    p, q = (x - c) * w[:, None], (x_ref - c_ref) * w[:, None]
    a_pq, a_qq = p.T @ q, q.T @ q
    eps = 1e-6 * jnp.maximum(jnp.trace(a_qq), 1e-30)
    affine = jnp.linalg.solve(a_qq + eps * jnp.eye(3, dtype=x.dtype), a_pq.T).T
    u, sig, vt = jnp.linalg.svd(affine)
    flip = _proper(u, vt)
    lam = jnp.maximum(sig * flip, 1.0 / max_stretch)  # no collapse or inversion
    lam = lam / jnp.prod(lam) ** (1.0 / 3.0)
    lam = jnp.clip(lam, 1.0 / max_stretch, max_stretch)
    return (u * (flip * lam)) @ vt


def coherence(
    x: jax.Array,
    x_ref: jax.Array,
    clot_mask: jax.Array,
    *,
    stiffness: float,
    tolerance: float = 0.0,
    keep_centroid: bool = False,
    max_stretch: jax.Array | float | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Shape matching of the clot to its rest shape. Jittable, vmappable.

    Each clot node is pulled toward its place ``g_i = R (x_ref_i - c_ref) + c`` in the best rigid
    copy of the rest shape: ``x_i += stiffness * (e_i - clip(e_i, tolerance))`` with deviation
    ``e_i = g_i - x_i`` and ``clip`` shortening a vector to at most ``tolerance``. A rigidly
    moved clot is left unchanged; nodes outside ``clot_mask`` are untouched. With
    ``max_stretch`` the copy is ``g_i = R S (x_ref_i - c_ref) + c`` with ``S`` the clot's own
    stretch from its affine fit, volume-preserving and bounded (a clot so stretched within
    the bounds and without a change of volume, is left unchanged too). Meant for the
    rollout, not for gradients: the SVD's derivative is undefined where singular values repeat.

    Args:
        x: ``[N, 3]`` current positions.
        x_ref: ``[N, 3]`` rest positions (e.g. the clot's first frame).
        clot_mask: ``[N]`` bool, the clot's real nodes (one body).
        stiffness: in [0, 1]; 0 does nothing, 1 snaps to the rigid copy (beyond ``tolerance``).
        tolerance: deviation from the rigid copy allowed without correction (>= 0).
        keep_centroid: take the clot nodes' mean move out of every clot node's move (static),
            so the clot's centroid stays where the step put it. Without a tolerance the
            moves already sum to zero (the rigid copy shares the clot's centroid, as in
            Mueller et al.'s shape matching, whose internal forces conserve momentum); with
            one, only the nodes beyond it move, and a clot stretched on one side (its front
            leaving the vessel first) is pulled back along its motion.
        max_stretch: ``None`` (static): the rigid copy. A number ``>= 1`` (traceable): the
            largest principal stretch (and the inverse of the smallest) the copy may take;
            1 gives a rigid copy again (turned by the affine fit's rotation, which may differ
            a little from the rigid fit's when the clot is deformed).
    Returns:
        ``(x_new [N, 3], correction [N])``.
    """
    w = clot_mask.astype(x.dtype)
    c, c_ref = _centroids(x, x_ref, w)
    linear = (_rigid_rotation(x, x_ref, w, c, c_ref) if max_stretch is None
              else _bounded_affine(x, x_ref, w, c, c_ref, max_stretch))
    goal = (x_ref - c_ref) @ linear.T + c
    dev = goal - x
    norm = safe_norm(dev, keepdims=True)
    excess = dev * jnp.maximum(1.0 - tolerance / jnp.maximum(norm, 1e-30), 0.0)
    move = jnp.where(clot_mask[:, None], stiffness * excess, 0.0)
    if keep_centroid:
        mean = jnp.sum(move, axis=0) / jnp.maximum(jnp.sum(w), 1.0)
        move = jnp.where(clot_mask[:, None], move - mean, 0.0)
    return x + move, safe_norm(move)


def relax_edges(
    x: jax.Array,
    x_ref: jax.Array,
    senders: jax.Array,
    receivers: jax.Array,
    movable_mask: jax.Array,
    *,
    max_strain: float,
    iterations: int = 4,
) -> tuple[jax.Array, jax.Array]:
    """Bring edge lengths back within ``(1 +- max_strain)`` of their rest length. Jittable.

    Args:
        x, x_ref: ``[N, 3]`` current and rest positions.
        senders, receivers: ``[E]`` int edge ends (each undirected edge once); entries outside
            ``[0, N)`` (sentinels) and edges with an end not in ``movable_mask`` are ignored.
        movable_mask: ``[N]`` bool.
        max_strain: allowed relative change of an edge's length (> 0).
        iterations: Jacobi sweeps (static).
    Returns:
        ``(x_new [N, 3], correction [N])``: positions and the distance each node moved in total.
    """
    n = x.shape[0]
    ok = (senders >= 0) & (senders < n) & (receivers >= 0) & (receivers < n)
    s, r = jnp.where(ok, senders, 0), jnp.where(ok, receivers, 0)
    ok = ok & movable_mask[s] & movable_mask[r]
    rest = jnp.linalg.norm(x_ref[s] - x_ref[r], axis=-1)

    def sweep(_, y):
        d = y[s] - y[r]
        length = safe_norm(d)
        target = jnp.clip(length, (1 - max_strain) * rest, (1 + max_strain) * rest)
        bad = ok & (jnp.abs(length - target) > 0)
        push = jnp.where(bad[:, None], 0.5 * (length - target)[:, None]
                         * d / jnp.maximum(length, 1e-30)[:, None], 0.0)
        delta = jax.ops.segment_sum(-push, s, n) + jax.ops.segment_sum(push, r, n)
        count = jax.ops.segment_sum(bad.astype(y.dtype), s, n) + jax.ops.segment_sum(
            bad.astype(y.dtype), r, n)
        return y + delta / jnp.maximum(count, 1.0)[:, None]

    x_new = jax.lax.fori_loop(0, iterations, sweep, x)
    x_new = jnp.where(movable_mask[:, None], x_new, x)
    return x_new, safe_norm(x_new - x)


def cell_edges(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges of cells (host-side): ``[C, k]`` -> ``(senders [E], receivers [E])``.

    Raises:
        ConfigError: ``cells`` is not a 2-D integer array with at least 2 columns.
    """
    cells = np.asarray(cells)
    if cells.ndim != 2 or cells.shape[1] < 2 or cells.dtype.kind not in "iu":
        raise ConfigError(f"cell_edges: cells must be an integer [C, k>=2] array, got "
                          f"{cells.dtype} {cells.shape}")
    k = cells.shape[1]
    pairs = np.concatenate([cells[:, [i, j]] for i in range(k) for j in range(i + 1, k)])
    pairs = np.unique(np.sort(pairs, axis=1), axis=0)
    return pairs[:, 0].astype(np.int32), pairs[:, 1].astype(np.int32)
