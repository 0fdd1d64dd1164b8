"""Per-node distance and direction to the nearest vessel node, under ``jit``, static shapes.

The wall features of a learned step (:class:`thrombojax.simulator.step.LearnedStep` with
``wall_cutoff > 0``): every clot node learns where the rigid wall is, also when no vessel node is
among its graph neighbours (a radius graph capped at K neighbours links a clot node inside the
clot only to clot nodes). The wall is represented by its nodes, which every dataset has (wall
triangles are optional), so the features need nothing but the frame itself::

    feats = wall_node_features(x, node_type, mask, cutoff=c)   # [N, 4]
    # [min(d, c) / c, unit vector to the nearest vessel node * (d < c)] on clot nodes, 0 elsewhere

The search is exact and dense: rows of ``block`` query nodes against all nodes, so the memory is
``block x N`` floats whatever ``N`` is (about 110 MB at 27,000 nodes). Distances are invariant
and directions rotate with the vessel, like the relative displacements a graph network sees.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from thrombojax.types import NodeType, clot_mask

__all__ = ["WALL_NODE_FEATURES", "WALL_NORMAL_NODES", "WALL_PLANE_NODES", "DENSE_PLANE_NODES",
           "clipped_distance_direction",
           "nearest_vessel_node", "wall_node_features", "clot_wall_mean", "local_wall_plane",
           "signed_wall_features", "wall_patches", "vessel_normals", "pairwise_sq_distances",
           "tie_key", "TIE_BITS", "smallest_first", "SEARCH_BLOCK", "first_min"]

WALL_NODE_FEATURES: int = 4
"""Width of :func:`wall_node_features`: clipped distance / cutoff and a 3-D direction."""

WALL_NORMAL_NODES: int = 12
"""Vessel nodes whose spread gives a vessel node's normal in :func:`local_wall_plane`."""

WALL_PLANE_NODES: int = 3
"""Nearest vessel nodes averaged by :func:`local_wall_plane` (as the host-side metric)."""

DENSE_PLANE_NODES: int = 8192
"""Most nodes :func:`local_wall_plane` takes (its ``N x N`` search: 800 MB at this size)."""


def pairwise_sq_distances(x: jax.Array) -> jax.Array:
    """``[N, N]`` squared distances between the points ``x [N, 3]``, one coordinate at a time.

    The same values as ``sum((x[:, None] - x[None]) ** 2, -1)`` up to rounding, but XLA's CPU
    code vectorises ``[N, N]`` planes and not a reduction over a minor axis of 3: 1.9 ms
    against 51 ms at 2,048 nodes (``docs/performance.md``)."""
    return sum((x[:, a][:, None] - x[:, a][None, :]) ** 2 for a in range(3))


def clipped_distance_direction(diff: jax.Array, cutoff: float) -> jax.Array:
    """``[..., 4]`` features of vectors ``diff [..., 3]`` from a node to its nearest wall point:
    ``min(d, cutoff) / cutoff`` and the unit vector times ``d < cutoff`` (zero when ``d`` is 0).
    The one formula of the wall features (also :func:`thrombojax.simulator.walls.wall_features`).
    """
    sq = jnp.sum(diff * diff, axis=-1)
    d = jnp.where(sq > 0, jnp.sqrt(jnp.where(sq > 0, sq, 1.0)), 0.0)  # zero gradient at 0
    near = (d < cutoff) & (d > 0)
    direction = jnp.where(near[..., None], diff / jnp.where(near, d, 1.0)[..., None], 0.0)
    return jnp.concatenate([jnp.minimum(d, cutoff)[..., None] / cutoff, direction], axis=-1)


def nearest_vessel_node(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, block: int = 1024
) -> jax.Array:
    """Index of the nearest real vessel node of every node. Jittable.

    Args:
        x: ``[N, 3]`` positions. node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        block: query rows per pass (memory ``block x N``).
    Returns:
        ``[N]`` int32 indices (0 for every node when there is no real vessel node).
    """
    n = x.shape[0]
    vessel = jnp.asarray(mask, bool) & (jnp.asarray(node_type) == NodeType.VESSEL)
    sq = jnp.sum(x * x, axis=-1)
    far = jnp.where(vessel, 0.0, jnp.inf)

    def rows(q: jax.Array) -> jax.Array:
        d2 = jnp.sum(q * q, axis=-1)[:, None] + sq[None, :] - 2.0 * q @ x.T + far[None, :]
        return first_min(d2)

    if n <= block:
        return rows(x)
    n_blocks = -(-n // block)
    padded = jnp.pad(x, ((0, n_blocks * block - n), (0, 0)))
    return jax.lax.map(rows, padded.reshape(n_blocks, block, 3)).reshape(-1)[:n]


def first_min(d: jax.Array) -> jax.Array:
    """``[T]`` int32 ``jnp.argmin(d, axis=1)`` of ``d [T, M]`` (the first minimum; the first NaN
    of a row holding one), as two reductions that XLA's CPU code vectorises: the minimum, then
    the lowest column holding it. ``argmin``'s single (value, index) reduction is not vectorised
    there: 3x slower at 2,048 nodes (``docs/performance.md``)."""
    m = jnp.min(d, axis=1, keepdims=True)  # NaN where the row holds one
    hit = (d == m) | (jnp.isnan(d) & jnp.isnan(m))
    cols = jnp.arange(d.shape[1], dtype=jnp.int32)
    return jnp.min(jnp.where(hit, cols[None, :], d.shape[1]), axis=1).astype(jnp.int32)


def wall_node_features(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, cutoff: float
) -> jax.Array:
    """Distance and direction to the nearest vessel node, clipped at ``cutoff``. Jittable.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped: these are inputs, like the graph).
        node_type: ``[N]`` NodeType. mask: ``[N]`` real nodes.
        cutoff: distance beyond which the wall is not felt (> 0, units of ``x``).
    Returns:
        ``[N, 4]``: ``min(d, cutoff) / cutoff`` and the unit vector from the node to its nearest
        vessel node times ``d < cutoff``, on real clot nodes; zeros on every other node.
    """
    if not cutoff > 0:
        raise ValueError(f"wall features: cutoff must be > 0, got {cutoff!r}")
    x = jax.lax.stop_gradient(x)
    j = nearest_vessel_node(x, node_type, mask)
    feats = clipped_distance_direction(x[j] - x, cutoff)
    has_wall = jnp.any(jnp.asarray(mask, bool) & (jnp.asarray(node_type) == NodeType.VESSEL))
    keep = clot_mask(node_type, mask) & has_wall
    return jnp.where(keep[:, None], feats, 0.0)


def clot_wall_mean(feats: jax.Array, node_type: jax.Array, mask: jax.Array) -> jax.Array:
    """The room the whole clot has in the vessel: the mean over real clot nodes of the first
    column of wall features ``feats [N, F]`` (the clipped distance / cutoff), ``[N, 1]`` on
    real clot nodes, zeros on every other node. Jittable.

    A clot's terminal speed follows the vessel's width (in ClotEntry, each simulation's speed
    correlates +0.4 to +0.7 with this mean at a 0.5 r cutoff), but a node's own distance says
    little about the clot as a whole, and a message-passing step sees only its neighbours:
    this gives every clot node the clot-wide figure.
    """
    clot = clot_mask(node_type, mask)
    w = clot.astype(feats.dtype)
    mean = jnp.sum(feats[:, 0] * w) / jnp.maximum(jnp.sum(w), 1.0)
    return jnp.where(clot, mean, 0.0)[:, None]


def wall_patches(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, k_normal: int = WALL_NORMAL_NODES
) -> jax.Array:
    """``[N, k_normal]`` int32: every node's ``k_normal`` nearest real vessel nodes, nearest
    first (the dense ``N x N`` search of :func:`local_wall_plane`). Jittable.

    A vessel node's row depends on the vessel's nodes alone, so in a rollout (the vessel is
    rigid) the rows of the vessel nodes are the same at every step: a search made once per
    rollout serves every step's vessel normals (:func:`vessel_normals`, the learned step's
    :meth:`~thrombojax.simulator.step.LearnedStep.context`). The rows of other nodes are those
    of the frame searched.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped). node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. k_normal: nodes per row (>= 3; at most ``N``).
    """
    _check_plane(x.shape[0])
    if k_normal < 1:
        raise ValueError(f"wall patches: need k_normal >= 1, got {k_normal!r}")
    x = jax.lax.stop_gradient(x)
    vessel = jnp.asarray(mask, bool) & (jnp.asarray(node_type) == NodeType.VESSEL)
    key = jnp.where(vessel[None, :], tie_key(pairwise_sq_distances(x)), jnp.inf)
    return smallest_first(key, min(k_normal, x.shape[0]))


SEARCH_BLOCK: int = 16
"""Columns per block of :func:`smallest_first`'s pruning."""


def smallest_first(key: jax.Array, k: int) -> jax.Array:
    """``[T, k]`` int32: the columns of the ``k`` smallest entries of every row of ``key [T, M]``,
    smallest first, equal keys by the lower column: exactly ``lax.top_k(-key, k)[1]``. Jittable.

    ``lax.top_k`` over all ``M`` columns is a single-threaded partial sort on the CPU, most of a
    training step's wall search at 2,048 nodes. Exact pruning instead: the columns are cut into
    blocks of :data:`SEARCH_BLOCK` consecutive columns; the ``k`` smallest entries lie in the
    ``k`` blocks with the smallest minima (equal minima: the lower block), since any other block
    is preceded by ``k`` blocks each holding an entry that ranks before all of its own. So
    ``top_k`` runs over the ``T x M / 16`` block minima and the ``16 k`` entries of the blocks
    kept, in column order. Measured 2.4x faster on a 2,048-node tube numbered ring by ring, as
    meshes are, the slow case of ``lax.top_k`` (``docs/performance.md``); at about 1,000 nodes it
    is no faster, so rows of fewer than ``8 k`` blocks use ``lax.top_k`` directly. ``key`` holds
    no NaN (:func:`tie_key` gives none).
    """
    t, m = key.shape
    s = SEARCH_BLOCK
    nb = -(-m // s)
    if nb < 8 * k:
        return jax.lax.top_k(-key, k)[1]
    blocks = jnp.pad(key, ((0, 0), (0, nb * s - m)), constant_values=jnp.inf).reshape(t, nb, s)
    _, kept = jax.lax.top_k(-jnp.min(blocks, axis=2), k)  # [t, k] blocks
    kept = jnp.sort(kept, axis=1)  # column order, so that top_k's ties go to the lower column
    vals = jnp.take_along_axis(blocks, kept[:, :, None], axis=1).reshape(t, k * s)
    _, pos = jax.lax.top_k(-vals, k)
    cols = (kept[:, :, None] * s + jnp.arange(s, dtype=kept.dtype)).reshape(t, k * s)
    return jnp.take_along_axis(cols, pos, axis=1).astype(jnp.int32)


TIE_BITS: int = 13
"""Low mantissa bits :func:`tie_key` drops: squared distances within about ``2**-10`` (0.1 %)
of each other rank as equal."""


def tie_key(sq: jax.Array) -> jax.Array:
    """A ranking key of squared distances ``sq >= 0`` that breaks ties the same way in every
    orientation. Jittable.

    A wall mesh has many vessel nodes at exactly the same distance from a node (rings of a
    tube). Computed in turned coordinates, those distances differ by rounding, so a plain
    ``top_k`` picked a different set of nearest nodes for a quarter of BendVessel's nodes at
    each orientation, and a wall normal could turn by 60 degrees (the patch fell on one ring):
    the wall and vessel-axis features, and a step in the vessel's frame, were not invariant to
    a rotation. The key drops the last :data:`TIE_BITS` bits of the float32 mantissa (for
    non-negative floats the bit pattern orders like the value), so rounding-level differences
    become exact ties, which ``lax.top_k`` breaks by the lower node index, an order no rotation
    changes. A tie whose rounding straddles a bin edge can still split (rare: no row of
    BendVessel's 977 nodes did at three random orientations); distances closer than the bin
    rank by index instead of by distance. (:func:`nearest_vessel_node`, behind the unsigned
    wall features, still ranks by its expanded ``|q|^2 + |x|^2 - 2 q.x``, whose rounding is
    larger than the bin.)
    """
    bits = jax.lax.bitcast_convert_type(jnp.asarray(sq, jnp.float32), jnp.int32)
    return jnp.right_shift(bits, TIE_BITS).astype(jnp.float32)  # < 2**18: exact in float32


def _check_plane(n: int, k_normal: int = 3, k_avg: int = 1) -> None:
    if n > DENSE_PLANE_NODES:
        raise ValueError(f"local wall plane: {n} nodes; its dense search is meant for "
                         f"at most {DENSE_PLANE_NODES} (signed wall features, vessel-axis "
                         "features and wall noise are for training-size clouds: subsample, "
                         "e.g. --nodes-per-sample in training, --nodes in a rollout)")
    if k_normal < 3 or k_avg < 1:
        raise ValueError(f"local wall plane: need k_normal >= 3 and k_avg >= 1, got "
                         f"{k_normal!r}, {k_avg!r}")


def _oriented_normals(x, node_type, mask, patch):
    """Unit normals of every row's patch (least spread), turned away from the clot centroid;
    ``patch`` from :func:`wall_patches` of a frame with the same vessel."""
    clot = clot_mask(node_type, mask)
    pts = x[patch]
    dev = pts - pts.mean(axis=1, keepdims=True)
    _, vecs = jnp.linalg.eigh(jnp.einsum("nki,nkj->nij", dev, dev))
    normals = vecs[:, :, 0]  # least spread: the normal of the node's own patch (vessel nodes)
    clot_centre = jnp.sum(jnp.where(clot[:, None], x, 0.0), axis=0) / jnp.maximum(clot.sum(), 1)
    return jnp.where((jnp.sum((x - clot_centre) * normals, axis=-1) < 0)[:, None],
                     -normals, normals)


def _plane_ok(node_type, mask, k_normal: int) -> jax.Array:
    mask = jnp.asarray(mask, bool)
    vessel = mask & (jnp.asarray(node_type) == NodeType.VESSEL)
    return (jnp.sum(vessel) >= k_normal) & jnp.any(clot_mask(node_type, mask))


def _averaged_normal(normals, near):
    normal = normals[near].mean(axis=1)
    return normal / jnp.maximum(jnp.linalg.norm(normal, axis=-1, keepdims=True), 1e-12)


def local_wall_plane(
    x: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    *,
    k_normal: int = WALL_NORMAL_NODES,
    k_avg: int = WALL_PLANE_NODES,
) -> tuple[jax.Array, jax.Array]:
    """Signed distance to the wall and outward wall normal of every node. Jittable.

    The host-side containment metric's construction (``thrombojax.eval.metrics``) from the
    frame alone: every real vessel node gets a unit normal, the direction of least spread of
    its ``k_normal`` nearest vessel nodes (the eigenvector of their covariance with the smallest
    eigenvalue), turned away from the centroid of the real clot nodes (the clot lies inside the
    vessel; right for the wall near the clot, which is where it is used). A node's signed
    distance is the mean of ``(x - w) . n_w`` over its ``k_avg`` nearest vessel nodes ``w``
    (positive outside) and its normal the normalised mean of their normals. Open vessel ends
    are not detected: a node past an outlet reads as inside or outside its rim's planes. The
    search is dense (``N x N`` distances, :func:`wall_patches`): meant for training windows,
    not 27,000-node frames.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped). node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. k_normal: vessel nodes per normal (>= 3).
        k_avg: vessel nodes averaged per node (>= 1).
    Returns:
        ``(signed [N], normal [N, 3])``; zeros on every node when there are fewer than
        ``k_normal`` real vessel nodes or no real clot node.
    """
    _check_plane(x.shape[0], k_normal, k_avg)
    x = jax.lax.stop_gradient(x)
    k_normal, k_avg = min(k_normal, x.shape[0]), min(k_avg, x.shape[0])
    patch = wall_patches(x, node_type, mask, k_normal=k_normal)  # [N, k_normal]
    normals = _oriented_normals(x, node_type, mask, patch)
    # the barrier keeps XLA from fusing the gathers below into the search (measured 8x slower)
    normals, patch = jax.lax.optimization_barrier((normals, patch))
    near = patch[:, :k_avg]  # top_k is sorted: the k_avg nearest vessel nodes
    signed = jnp.mean(jnp.sum((x[:, None, :] - x[near]) * normals[near], axis=-1), axis=1)
    normal = _averaged_normal(normals, near)
    ok = _plane_ok(node_type, mask, k_normal)
    return jnp.where(ok, signed, 0.0), jnp.where(ok, normal, 0.0)


def vessel_normals(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, patch: jax.Array, *,
    k_avg: int = WALL_PLANE_NODES,
) -> jax.Array:
    """``[N, 3]``: :func:`local_wall_plane`'s normal on every real vessel node, from a search
    made before (``patch = wall_patches(x0, ...)`` of any frame with the same vessel nodes,
    e.g. a rollout's first). Jittable; no ``N x N`` search.

    Equal on vessel rows to ``local_wall_plane(x, node_type, mask)[1]`` when the vessel nodes
    of ``x`` are where they were in the searched frame (a rollout copies them exactly); the
    rows of other nodes are not meaningful (their search is of the old frame). Zeros on every
    node when the plane is undefined (as :func:`local_wall_plane`).

    Args:
        x: ``[N, 3]`` positions (gradients are stopped). node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. patch: ``[N, k_normal]`` from :func:`wall_patches`.
        k_avg: vessel nodes averaged per node (as :func:`local_wall_plane`).
    """
    k_normal = patch.shape[-1]
    _check_plane(x.shape[0], k_avg=k_avg)
    x = jax.lax.stop_gradient(x)
    normals = _oriented_normals(x, node_type, mask, patch)
    normal = _averaged_normal(normals, patch[:, :min(k_avg, x.shape[0])])
    return jnp.where(_plane_ok(node_type, mask, k_normal), normal, 0.0)


def signed_wall_features(
    x: jax.Array, node_type: jax.Array, mask: jax.Array, *, cutoff: float
) -> jax.Array:
    """The wall features from the signed wall distance (:func:`local_wall_plane`). Jittable.

    Unlike :func:`wall_node_features` (the distance to the nearest vessel node, the same
    inside and outside) these tell a node that crossed the wall from one inside it.

    Args:
        x: ``[N, 3]`` positions (gradients are stopped). node_type: ``[N]`` NodeType.
        mask: ``[N]`` real nodes. cutoff: distance beyond which the wall is not felt (> 0).
    Returns:
        ``[N, 4]``: ``clip(signed, -cutoff, cutoff) / cutoff`` (positive outside) and the unit
        outward normal times ``|signed| < cutoff``, on real clot nodes; zeros elsewhere.
    """
    if not cutoff > 0:
        raise ValueError(f"wall features: cutoff must be > 0, got {cutoff!r}")
    signed, normal = local_wall_plane(x, node_type, mask)
    near = (jnp.abs(signed) < cutoff)[:, None]
    feats = jnp.concatenate([jnp.clip(signed, -cutoff, cutoff)[:, None] / cutoff,
                             jnp.where(near, normal, 0.0)], axis=-1)
    return jnp.where(clot_mask(node_type, mask)[:, None], feats, 0.0)
