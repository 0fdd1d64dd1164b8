"""Wall distance/direction features, rest-state edge features and the outside fraction."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from wall_factory import bent_vessel

from thrombojax.sim.geometry import rotation_matrix
from thrombojax.simulator.guards import wall_from_simulation
from thrombojax.simulator.walls import (
    WALL_FEATURES,
    fraction_outside_wall,
    wall_features,
)

CUTOFF = 1.0


def flat_wall_positions(n: int = 9):
    """A square of wall nodes in the plane z = 0 (side 4) with its triangles, and 4 clot nodes
    above it (z > 0 is inside)."""
    g = np.linspace(-2.0, 2.0, n)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    wall = np.stack([gx.ravel(), gy.ravel(), np.zeros(n * n)], 1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    tris = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    clot = np.array([[0.0, 0.0, 0.5], [0.3, 0.1, 0.4], [-0.2, 0.3, 0.6], [0.1, -0.4, 0.5]])
    positions = np.concatenate([clot, wall])
    node_type = np.array([1] * len(clot) + [0] * len(wall), np.int8)
    return positions, node_type, tris + len(clot)


@pytest.fixture(scope="module", params=["triangles", "nodes"])
def flat_wall(request):
    positions, node_type, cells = flat_wall_positions()
    return wall_from_simulation(positions, node_type,
                                cells if request.param == "triangles" else None)


def test_distance_and_direction_to_a_flat_wall(flat_wall):
    x = jnp.array([[0.1, 0.2, 0.3], [-0.3, 0.1, -0.2], [0.2, 0.2, 2.5], [0.0, 0.0, 0.0]])
    feats = jax.jit(lambda y, m: wall_features(y, flat_wall, cutoff=CUTOFF, node_mask=m))
    f = feats(x, jnp.ones(4, bool))
    assert f.shape == (4, WALL_FEATURES)
    np.testing.assert_allclose(f[0], [0.3, 0.0, 0.0, -1.0], atol=1e-5)  # inside: toward -z
    np.testing.assert_allclose(f[1], [0.2, 0.0, 0.0, 1.0], atol=1e-5)  # outside: toward +z
    np.testing.assert_allclose(f[2], [1.0, 0.0, 0.0, 0.0], atol=1e-6)  # beyond the cutoff
    np.testing.assert_allclose(f[3], [0.0, 0.0, 0.0, 0.0], atol=1e-6)  # on the wall
    masked = feats(x, jnp.array([1, 0, 1, 1], bool))
    np.testing.assert_array_equal(np.asarray(masked[1]), 0.0)
    np.testing.assert_allclose(masked[0], f[0], atol=1e-6)
    # differentiable (k-step losses through the features), also on the wall itself
    grad = jax.jit(jax.grad(lambda y: feats(y, jnp.ones(4, bool)).sum()))(x)
    assert np.isfinite(np.asarray(grad)).all()


def test_fraction_outside_counts_clot_nodes_through_the_wall(flat_wall):
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.uniform(-1, 1, (10, 2)), rng.uniform(0.1, 0.8, (10, 1))], 1)
    x[[2, 5, 7], 2] = -0.3  # three clot nodes through the wall
    x[8, 2] = -0.5  # ... and one that does not count (not clot)
    clot = np.ones(10, bool)
    clot[8] = False
    frac = jax.jit(lambda y, m: fraction_outside_wall(y, m, flat_wall))
    assert float(frac(jnp.asarray(x), jnp.asarray(clot))) == pytest.approx(3 / 9)
    assert float(frac(jnp.asarray(x), jnp.zeros(10, bool))) == 0.0


@pytest.mark.parametrize("kind", ["triangles", "nodes"])
def test_wall_features_rotate_with_the_vessel(kind):
    vessel = bent_vessel(seed=2)
    rot = rotation_matrix("z", 70.0) @ rotation_matrix("y", -40.0) @ rotation_matrix("x", 25.0)
    x = vessel["positions"][vessel["clot"]]
    feats = []
    for r in (np.eye(3), rot):
        pos = vessel["positions"] @ r.T
        cells = vessel["wall_cells"] if kind == "triangles" else None
        wall = wall_from_simulation(pos, vessel["node_type"], cells)
        feats.append(np.asarray(jax.jit(lambda y, w=wall: wall_features(y, w, cutoff=0.6))(
            jnp.asarray(x @ r.T, jnp.float32))))
    base, turned = feats
    assert (base[:, 0] < 1).mean() > 0.3, "too few nodes near the wall to test anything"
    np.testing.assert_allclose(turned[:, 0], base[:, 0], atol=2e-5)
    np.testing.assert_allclose(turned[:, 1:], base[:, 1:] @ rot.T, atol=2e-4)
