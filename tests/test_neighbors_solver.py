"""Radius graph on real solver frames (the initial frame of a ClotEntry case, scaled to
[-1, 1]) against scipy cKDTree, at N = 100, 2,048 (subsets) and 26,999 (full resolution)."""

import jax
import numpy as np
import pytest
from test_neighbors import K, assert_matches

from thrombojax.data.scaling import fit_scaling
from thrombojax.graph import estimate_capacity, radius_graph
from thrombojax.sim.cases import build_case
from thrombojax.sim.presets import get_preset


@pytest.fixture(scope="module")
def clotentry_frame():
    """Clot nodes then wall nodes of ClotEntry simulation 0 at its first frame, scaled."""
    case = build_case(get_preset("clotentry"), 0, seed=0)
    x = np.concatenate([np.asarray(case.params.x0), case.wall_points]) @ case.rotation.T
    return np.asarray(fit_scaling(x[None]).apply(x), np.float32)


@pytest.mark.parametrize("n", [100, 2048])
def test_dense_on_a_solver_frame_subset(clotentry_frame, n):
    rng = np.random.default_rng(n)
    x = clotentry_frame[np.sort(rng.choice(len(clotentry_frame), n, replace=False))]
    nbrs = jax.jit(lambda p: radius_graph(p, 0.56, K))(x)
    assert_matches(nbrs, x, 0.56, K)


def test_grid_on_the_full_solver_frame(clotentry_frame):
    x = clotentry_frame
    assert len(x) == 26_999
    spec = estimate_capacity(x, 0.576, K)
    nbrs = jax.jit(lambda p: radius_graph(p, 0.576, K, grid=spec, method="grid"))(x)
    # the wall's rings of points make many exact distance ties: distances are compared
    # exactly, indices of tied neighbours may differ from cKDTree's order
    assert_matches(nbrs, x, 0.576, K, exact_counts=spec.cell_size >= 0.576, min_same_rows=0.9)
