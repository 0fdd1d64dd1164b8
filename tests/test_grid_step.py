"""Full-resolution steps on the cell grid: same graph and outputs as the dense search, overflow
flagged and re-allocated on the host (or a clear error), small clouds unchanged bit for bit."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest

from thrombojax.errors import CapacityOverflowError, ConfigError
from thrombojax.eval.bench import time_rollout
from thrombojax.graph.capacity import estimate_capacity
from thrombojax.graph.neighbors import AUTO_GRID_MIN_NODES, graph_overflow
from thrombojax.models.registry import EmptyGraph, create_model, get_config, identity_stats
from thrombojax.simulator.grid_step import allocate_grid, run_checked
from thrombojax.simulator.rollout import rollout, rollout_jit, unroll
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

N_LARGE = AUTO_GRID_MIN_NODES  # the smallest cloud on which "auto" may choose the grid


def _cloud(n, seed=0):
    """A random cloud in [-1, 1]^3 (30 % clot nodes moving slightly): no exact distance ties."""
    rng = np.random.default_rng(seed)
    x_cur = rng.uniform(-1.0, 1.0, (n, 3)).astype(np.float32)
    node_type = np.where(rng.uniform(size=n) < 0.3, NodeType.CLOT, NodeType.VESSEL)
    x_prev = x_cur - np.where(node_type[:, None] == NodeType.CLOT, 1e-3, 0.0).astype(np.float32)
    return x_prev, x_cur, node_type.astype(np.int32), np.ones(n, bool)


def _step_call(step, params, stats, state):
    return jax.jit(step)(params, stats, *state)


def _tiny_step(name, n):
    model = create_model(name, get_config(name, tiny=True))
    step = make_step(model)
    state = _cloud(n)
    params = step.init(jax.random.key(0), *state)
    return step, params, state


def _too_small(spec):
    """The spec with one slot per run: every real node overflows it."""
    return dataclasses.replace(spec, capacity=1, heavy_capacity=1)


def test_mgn_on_the_grid_equals_dense():
    step, params, state = _tiny_step("mgn", N_LARGE)
    stats = identity_stats()
    gridded = allocate_grid(step, np.stack(state[:2]), state[2])
    assert gridded.grid is not None and step.grid is None
    inputs = step.inputs(stats, *state)
    dense_graph = jax.jit(step.build_graph)(inputs)
    grid_graph = jax.jit(gridded.build_graph)(inputs)
    assert not bool(grid_graph.overflow)
    np.testing.assert_array_equal(np.asarray(grid_graph.indices), np.asarray(dense_graph.indices))
    dense = _step_call(step, params, stats, state)
    on_grid = _step_call(gridded, params, stats, state)
    assert not bool(on_grid.overflow) and not bool(dense.overflow)
    np.testing.assert_allclose(np.asarray(on_grid.output), np.asarray(dense.output), atol=1e-5)
    np.testing.assert_allclose(np.asarray(on_grid.positions), np.asarray(dense.positions),
                               atol=1e-5)


@pytest.mark.parametrize("name", ["mgn", "transolver", "erwin"])
def test_every_graph_model_uses_the_grid(name):
    """A grid with one slot per run must overflow: a model that ignored it would not."""
    model = create_model(name, get_config(name, tiny=True))
    step = make_step(model)
    state = _cloud(N_LARGE)
    inputs = step.inputs(identity_stats(), *state)
    spec = allocate_grid(step, state[1], state[2]).grid
    assert spec is not None
    good = jax.jit(step.with_grid(spec).build_graph)(inputs)
    assert not bool(graph_overflow(good))
    nbrs = getattr(good, "neighbors", good)
    dense = jax.jit(step.build_graph)(inputs)
    dense = getattr(dense, "neighbors", dense)
    np.testing.assert_array_equal(np.asarray(nbrs.indices), np.asarray(dense.indices))
    bad = jax.jit(step.with_grid(_too_small(spec)).build_graph)(inputs)
    assert bool(graph_overflow(bad))


def test_step_reports_overflow_and_rollout_reallocates():
    step, params, state = _tiny_step("mgn", N_LARGE)
    stats = identity_stats()
    spec = allocate_grid(step, np.stack(state[:2]), state[2]).grid
    small = step.with_grid(_too_small(spec))
    assert bool(_step_call(small, params, stats, state).overflow)

    # the compiled rollout accumulates the flag over its steps
    _, _, overflow = rollout_jit(small, params, stats, *state, 2, None)
    assert bool(overflow)

    grids = []

    def run(s):
        grids.append(s.grid)
        _, _, flag = rollout_jit(s, params, stats, *state, 2, None)
        return None, flag

    _, final = run_checked(run, small, max_regrows=8)
    assert len(grids) > 1 and final.grid.capacity > 1 and grids[-1] == final.grid

    traj = rollout(small, params, stats, *state, 2, max_regrows=8)
    want = rollout(step, params, stats, *state, 2)
    np.testing.assert_allclose(np.asarray(traj), np.asarray(want), atol=1e-5)


def test_overflow_without_reallocation_is_a_clear_error():
    step, params, state = _tiny_step("mgn", N_LARGE)
    spec = allocate_grid(step, np.stack(state[:2]), state[2]).grid
    small = step.with_grid(_too_small(spec))
    with pytest.raises(CapacityOverflowError, match=r"0 re-allocation.*capacity 1 nodes per run"):
        rollout(small, params, identity_stats(), *state, 1, max_regrows=0)


def test_small_clouds_are_unchanged_bit_for_bit():
    """Below AUTO_GRID_MIN_NODES nothing is allocated and even a given grid is not used."""
    step, params, state = _tiny_step("mgn", 977)
    stats = identity_stats()
    assert allocate_grid(step, np.stack(state[:2]), state[2]).grid is None
    spec = estimate_capacity(state[1], step.model.config.radius, step.model.config.max_neighbors)
    gridded = step.with_grid(spec)
    plain, with_grid = _step_call(step, params, stats, state), _step_call(gridded, params, stats,
                                                                          state)
    np.testing.assert_array_equal(np.asarray(plain.output), np.asarray(with_grid.output))
    np.testing.assert_array_equal(np.asarray(plain.positions), np.asarray(with_grid.positions))
    np.testing.assert_array_equal(np.asarray(rollout(step, params, stats, *state, 3)),
                                  np.asarray(rollout(gridded, params, stats, *state, 3)))


def test_unchecked_consumers_refuse_a_grid_and_no_graph_has_no_overflow():
    step, params, state = _tiny_step("mgn", 64)
    spec = estimate_capacity(state[1], 0.56, 8)
    with pytest.raises(ConfigError, match="overflow flag"):
        unroll(step.with_grid(spec), params, identity_stats(), *state, 2)
    assert not bool(graph_overflow(EmptyGraph()))
    baseline = make_step(create_model("constant_velocity"))
    assert allocate_grid(baseline, np.zeros((N_LARGE, 3)), np.zeros(N_LARGE, int)).grid is None
    with pytest.raises(ConfigError, match="frames must be"):
        allocate_grid(step, np.zeros((2, 5)), np.zeros(5, int))


def test_bench_times_full_resolution_rollouts_on_the_grid():
    step, params, state = _tiny_step("mgn", N_LARGE)
    timed = time_rollout(step, params, identity_stats(), *state[:3], 1, repeats=1)
    assert timed["graph"] == "grid" and timed["grid"].startswith("GridSpec(") and timed["finite"]
    dense = time_rollout(step, params, identity_stats(), *state[:3], 1, repeats=1, grid=False)
    assert dense["graph"] == "dense" and dense["grid"] is None
