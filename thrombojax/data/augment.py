"""Data augmentations of one training window (s_{t-1}, s_t, s_{t+1}): pure functions with a seed.

Three augmentations of the study, each applied identically to the
three frames of a window so the dynamics stay consistent:

* :func:`random_rotation` / :func:`rotate_window`: a random rotation about a random axis
  (uniform on the sphere) by an angle uniform in ``[0, max_angle]`` radians. The rotation is
  about the origin of the *scaled* frame (the dataset's centre after :class:`Scaling`), so a
  rotated sample stays inside roughly the same box; pairwise distances, velocities' norms and
  node types are unchanged.
* :func:`subsample_indices`: ``n`` of the ``N`` nodes (numpy, on the host), the clot fraction
  kept, the same indices for all frames (ClotEntry: 2048 of ~27,000).
* :func:`barycentric_resample`: the study's *BaryCentricSampling* (thesis, Algorithm 1): every
  generated point is ``c1 p1 + c2 p2 + c3 p3`` on a triangle of the edge set, with one set of
  coefficients ``(c1, c2, c3) >= 0``, ``sum = 1`` (uniform on the simplex, Dirichlet(1, 1, 1))
  for all three frames, so the point moves with its triangle. Triangles come from
  :mod:`thrombojax.graph.triangles` on the radius graph of s_t. Choice where the thesis is
  silent: a generated sample has as many points as its source sample, each real node is replaced
  by a point on a random triangle *of its own node type* (three clot vertices for a clot point,
  three vessel vertices for a vessel point), so the clot:vessel composition is kept and vessel
  points stay rigid; a node type without triangles keeps its nodes unchanged.

Everything except :func:`subsample_indices` is jittable and works on one sample (no batch axis).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.graph.neighbors import radius_graph
from thrombojax.types import NUM_NODE_TYPES, NodeType

__all__ = [
    "AugmentConfig",
    "augment_batch",
    "random_rotation",
    "haar_angle",
    "rotate_window",
    "subsample_indices",
    "barycentric_resample",
    "find_sample_triangles",
]


def random_rotation(key: jax.Array, max_angle: float | jax.Array,
                    uniform: bool = False) -> jax.Array:
    """A random rotation matrix: axis uniform on the sphere, angle in ``[0, max_angle]``.

    The angle is uniform in ``[0, max_angle]`` (the study's augmentation), or with ``uniform``
    drawn with the density ``(1 - cos t)`` of the uniform (Haar) measure on the rotations,
    restricted to angles up to ``max_angle``: with ``max_angle = pi`` every orientation is then
    equally likely. The uniform-angle draw is not: it turns a window by less than 45 degrees a
    quarter of the time, where a uniformly random rotation does so 2.5 % of the time, so the
    dataset's own orientations are ten times over-represented in training.

    Args:
        key: PRNG key.
        max_angle: the largest angle in radians (``pi`` = the study's best setting; 0 = identity).
        uniform: the angle of the uniform measure (above), not a uniform angle.
    Returns:
        ``[3, 3]`` float32 orthogonal matrix with determinant +1 (Rodrigues' formula).
    """
    k_axis, k_angle = jax.random.split(key)
    axis = jax.random.normal(k_axis, (3,), jnp.float32)
    axis = axis / jnp.maximum(jnp.linalg.norm(axis), 1e-12)
    u = jax.random.uniform(k_angle, (), jnp.float32)
    max_angle = jnp.asarray(max_angle, jnp.float32)
    angle = haar_angle(u, max_angle) if uniform else u * max_angle
    x, y, z = axis[0], axis[1], axis[2]
    zero = jnp.zeros((), jnp.float32)
    cross = jnp.stack(
        [jnp.stack([zero, -z, y]), jnp.stack([z, zero, -x]), jnp.stack([-y, x, zero])]
    )
    eye = jnp.eye(3, dtype=jnp.float32)
    return eye + jnp.sin(angle) * cross + (1.0 - jnp.cos(angle)) * (cross @ cross)


def haar_angle(u: jax.Array, max_angle: jax.Array, iterations: int = 40) -> jax.Array:
    """The angle ``t`` in ``[0, max_angle]`` with ``t - sin t = u (m - sin m)``, ``m =
    max_angle <= pi``: the inverse of the distribution function of the rotation angle under
    the uniform measure on the rotations (density ``(1 - cos t) / pi`` on ``[0, pi]``), so
    ``u`` uniform in ``[0, 1]`` gives that angle. Bisection (``t - sin t`` increases on
    ``[0, pi]``); jittable."""
    m = jnp.minimum(jnp.asarray(max_angle, jnp.float32), jnp.pi)
    target = u * (m - jnp.sin(m))

    def halve(_, bounds):
        lo, hi = bounds
        mid = 0.5 * (lo + hi)
        below = mid - jnp.sin(mid) < target
        return jnp.where(below, mid, lo), jnp.where(below, hi, mid)

    lo, hi = jax.lax.fori_loop(0, iterations, halve, (jnp.zeros_like(m), m))
    return 0.5 * (lo + hi)


def rotate_window(frames: jax.Array, rotation: jax.Array) -> jax.Array:
    """Rotate every frame of a window about the origin of the scaled frame.

    Args:
        frames: ``[..., n_nodes, 3]`` positions (e.g. ``[3, n_nodes, 3]`` for a window).
        rotation: ``[3, 3]`` rotation matrix.
    Returns:
        Rotated positions, same shape: ``x @ R^T``.
    """
    return frames @ rotation.T


def subsample_indices(
    rng: np.random.Generator | int, node_type: np.ndarray, n: int
) -> np.ndarray:
    """Choose ``n`` of the ``N`` nodes, keeping the clot fraction (host-side, numpy).

    The one node-subset rule of the package: training samples (``nodes_per_sample``), evaluation
    and rollouts on a fixed subset (the study's 2,048 nodes of ClotEntry) all call it.

    The number of clot nodes is ``round(n * N_clot / N)``, at least one when the sample has clot
    nodes, and never more than there are of either type. The same indices must be applied to
    every frame of the window.

    Args:
        rng: numpy generator (seeded by the caller, e.g. from (seed, epoch, position)), or an
            int seed (a fixed subset, e.g. for a rollout).
        node_type: ``[N]`` NodeType values.
        n: number of nodes wanted; ``n >= N`` returns all nodes.
    Returns:
        ``[min(n, N)]`` int64 sorted node indices.
    """
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(int(rng))
    node_type = np.asarray(node_type)
    total = node_type.shape[0]
    if n <= 0:
        raise ConfigError(f"nodes per sample must be positive, got {n}")
    if n >= total:
        return np.arange(total)
    clot = np.flatnonzero(node_type == NodeType.CLOT)
    vessel = np.flatnonzero(node_type != NodeType.CLOT)
    n_clot = int(round(n * clot.size / total))
    if clot.size > 0:
        n_clot = max(n_clot, 1)
    n_clot = min(n_clot, clot.size, n)
    n_clot = max(n_clot, n - vessel.size)
    n_vessel = n - n_clot
    chosen = np.concatenate(
        [rng.choice(clot, n_clot, replace=False), rng.choice(vessel, n_vessel, replace=False)]
    )
    return np.sort(chosen)


def find_sample_triangles(
    positions: jax.Array,
    mask: jax.Array,
    *,
    radius: float,
    max_neighbors: int,
) -> tuple[jax.Array, jax.Array]:
    """Triangles of the radius graph of one frame (the edge set of Algorithm 1), jittable.

    :func:`thrombojax.graph.triangles.find_triangles` is the host (numpy) reference; this is its
    fixed-shape version for ``jit``, so BaryCentricSampling runs on the device inside the input
    pipeline with no host round trip and no buffer that can overflow: every node ``i`` checks the
    ``K (K - 1) / 2`` pairs ``(a, b)`` of its own neighbour list (an edge ``a - b`` exists when
    either lists the other) and keeps a triangle when ``i`` is its smallest vertex, so each
    triangle appears once. When no neighbour list is capped (``counts <= K``) the set equals the
    reference's (tested); a capped list can only drop triangles, never invent one.

    Args:
        positions: ``[n_nodes, 3]`` positions s_t (scaled).
        mask: ``[n_nodes]`` real-node mask.
        radius, max_neighbors: the radius graph (:func:`thrombojax.graph.neighbors.radius_graph`).
    Returns:
        ``(triangles [n_nodes * K (K - 1) / 2, 3] int32, valid [same] bool)``, rows
        ``(i, a, b)`` with ``i < a < b`` where valid.
    """
    nbrs = radius_graph(positions, radius, max_neighbors, mask=mask)
    idx = nbrs.indices.astype(jnp.int32)
    n, k = idx.shape
    first, second = np.triu_indices(k, 1)
    a, b = idx[:, first], idx[:, second]  # [N, P] neighbour pairs of each node
    lo, hi = jnp.minimum(a, b), jnp.maximum(a, b)
    padded = jnp.concatenate([idx, jnp.full((1, k), n, jnp.int32)])  # row n: the sentinel's
    edge = jnp.any(padded[lo] == hi[..., None], axis=-1) | jnp.any(
        padded[hi] == lo[..., None], axis=-1
    )
    me = jnp.arange(n, dtype=jnp.int32)[:, None]
    valid = (hi < n) & edge & (me < lo)
    triangles = jnp.stack([jnp.broadcast_to(me, lo.shape), lo, hi], axis=-1)
    return triangles.reshape(-1, 3), valid.reshape(-1)


def barycentric_resample(
    key: jax.Array,
    frames: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    triangles: jax.Array,
    valid: jax.Array,
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """BaryCentricSampling (thesis Algorithm 1): a generated sample of points on triangles.

    Args:
        key: PRNG key.
        frames: ``[n_frames, n_nodes, 3]`` the window (s_{t-1}, s_t, s_{t+1}).
        node_type: ``[n_nodes]`` NodeType values. mask: ``[n_nodes]`` real-node mask.
        triangles: ``[M, 3]`` vertex indices. valid: ``[M]`` bool, the rows that are triangles.
    Returns:
        ``(new_frames [n_frames, n_nodes, 3], coefficients [n_nodes, 3], vertices [n_nodes, 3])``:
        node ``i`` of the generated sample is
        ``sum_k coefficients[i, k] * frames[:, vertices[i, k]]`` in every frame (the triangle is
        drawn uniformly among those of node ``i``'s type); it keeps node ``i``'s type and mask.
        Padded nodes, and nodes of a type without triangles, are copied (coefficients (1, 0, 0)).
    """
    n_nodes = node_type.shape[0]
    n_tri = triangles.shape[0]
    k_coef, k_pick = jax.random.split(key)
    coef = jax.random.dirichlet(k_coef, jnp.ones((3,), jnp.float32), (n_nodes,))
    tri_types = node_type[jnp.clip(triangles, 0, n_nodes - 1)]
    uniform = jax.random.uniform(k_pick, (n_nodes,))
    self_tri = jnp.broadcast_to(jnp.arange(n_nodes, dtype=jnp.int32)[:, None], (n_nodes, 3))
    vertices = self_tri
    for kind in range(NUM_NODE_TYPES):
        ok = valid & jnp.all(tri_types == kind, axis=1)
        cum = jnp.cumsum(ok.astype(jnp.int32))
        n_ok = cum[-1]
        rank = jnp.floor(uniform * n_ok).astype(jnp.int32) + 1  # 1 .. n_ok
        slot = jnp.clip(jnp.searchsorted(cum, rank, side="left"), 0, n_tri - 1)
        chosen = triangles[slot].astype(jnp.int32)
        use = (node_type == kind) & mask & (n_ok > 0)
        vertices = jnp.where(use[:, None], chosen, vertices)
    generated = jnp.logical_not(jnp.all(vertices == self_tri, axis=1))
    coef = jnp.where(generated[:, None], coef, jnp.array([1.0, 0.0, 0.0], jnp.float32))
    new_frames = jnp.einsum("nk,fnkd->fnd", coef, frames[:, vertices])
    return new_frames, coef, vertices


@dataclasses.dataclass(frozen=True)
class AugmentConfig:
    """Augmentations applied on the device to every training batch.

    Attributes:
        max_rotation: largest rotation angle in radians (0 disables rotations).
        uniform_rotation: draw the angle of the uniform measure on the rotations
            (:func:`random_rotation`), not a uniform angle.
        barycentric: whether the batch may contain generated (BaryCentricSampling) samples.
        radius, max_neighbors: the radius graph whose triangles BaryCentricSampling uses.
    """

    max_rotation: float = float(np.pi)
    uniform_rotation: bool = False
    barycentric: bool = False
    radius: float = 0.5
    max_neighbors: int = 16


def augment_batch(key: jax.Array, batch, config: AugmentConfig):
    """Replace generated samples by BaryCentricSampling, then rotate every sample (jittable).

    Args:
        key: PRNG key of the step.
        batch: a :class:`thrombojax.data.batching.Batch` (``frames [B, 3, N, 3]``).
        config: the augmentations.
    Returns:
        The augmented batch (same shapes).
    """

    def one(k, frames, node_type, mask, generated):
        k_bary, k_rot = jax.random.split(k)
        if config.barycentric:
            triangles, valid = find_sample_triangles(
                frames[1], mask, radius=config.radius, max_neighbors=config.max_neighbors
            )
            new, _, _ = barycentric_resample(k_bary, frames, node_type, mask, triangles, valid)
            frames = jnp.where(generated, new, frames)
        if config.max_rotation > 0:
            frames = rotate_window(frames, random_rotation(k_rot, config.max_rotation,
                                                           config.uniform_rotation))
        return frames

    keys = jax.random.split(key, batch.size)
    frames = jax.vmap(one)(keys, batch.frames, batch.node_type, batch.mask, batch.generated)
    return batch.replace(frames=frames)
