"""The rollout context: the rigid vessel's wall search made once per rollout, same results."""

import jax
import jax.extend.core as jax_core
import jax.numpy as jnp
import numpy as np
import pytest
from test_vessel_axis import _tube

from thrombojax.graph.vessel_axis import (
    axis_velocity_features,
    clot_lateral_mean,
    follow_axis_offset,
)
from thrombojax.graph.wall_nodes import (
    WALL_NORMAL_NODES,
    local_wall_plane,
    vessel_normals,
    wall_patches,
)
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.committee import _committee_impl
from thrombojax.simulator.ensemble import stack_params
from thrombojax.simulator.rollout import _scan, rollout_jit
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType, TargetStats


def _frames():
    """A tube with its clot at three places (the vessel nodes identical), float32 arrays."""
    rng = np.random.default_rng(3)
    d = np.array([1.0, 0.4, -0.3]) / np.linalg.norm([1.0, 0.4, -0.3])
    x, nt, _ = _tube(lambda s: s * d, lambda s: d, rng, n_wall=260, n_clot=24)
    clot = nt == NodeType.CLOT
    frames = []
    for shift in (0.0, 0.35, 0.8):
        y = x.copy()
        y[clot] += shift * d + rng.normal(0, 0.05, (clot.sum(), 3))
        frames.append(jnp.asarray(y, jnp.float32))
    return frames, jnp.asarray(nt), jnp.ones(len(nt), bool)


def _stats():
    return TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.05), velocity_std=jnp.asarray(0.1))


def test_vessel_normals_from_an_old_search_equal_a_new_search_on_the_vessel():
    (x0, x1, _), nt, mask = _frames()
    vessel = np.asarray(nt) == NodeType.VESSEL
    patch = wall_patches(x0, nt, mask)
    cached = np.asarray(vessel_normals(x1, nt, mask, patch))
    fresh = np.asarray(local_wall_plane(x1, nt, mask)[1])
    np.testing.assert_allclose(cached[vessel], fresh[vessel], atol=1e-6)
    # the clot rows of the old search are the old clot's: not what a new search gives there
    clot_rows_old = np.asarray(patch)[~vessel]
    assert not np.array_equal(clot_rows_old, np.asarray(wall_patches(x1, nt, mask))[~vessel])


@pytest.mark.parametrize("frame", ["global", "vessel"])
def test_a_step_given_the_context_returns_what_it_returns_without(frame):
    (x0, x1, x2), nt, mask = _frames()
    model = create_model("meshgraphnet", get_config("meshgraphnet", tiny=True))
    step = make_step(model, frame=frame, axis_radius=2.0, prior_radius=2.0, lateral_radius=2.0)
    params = step.init(jax.random.PRNGKey(0), x0, x1, nt, mask)
    context = step.context(x0, nt, mask)
    assert context.input_patch is not None and context.global_patch is not None
    plain = step(params, _stats(), x1, x2, nt, mask)
    cached = step(params, _stats(), x1, x2, nt, mask, context=context)
    np.testing.assert_allclose(np.asarray(cached.positions), np.asarray(plain.positions),
                               atol=1e-5)
    np.testing.assert_allclose(np.asarray(cached.output), np.asarray(plain.output), atol=1e-5)
    # the prior and the lateral hold move the clot: the comparison is not of zeros
    assert float(jnp.abs(plain.positions - x2).max()) > 1e-3


def test_steps_without_vessel_axis_inputs_have_no_context_and_axis_alone_one_search():
    (x0, _, _), nt, mask = _frames()
    model = create_model("meshgraphnet", get_config("meshgraphnet", tiny=True))
    assert make_step(model).context(x0, nt, mask) is None
    assert make_step(model, wall_cutoff=0.5, wall_signed=True).context(x0, nt, mask) is None
    axis = make_step(model, axis_radius=2.0).context(x0, nt, mask)
    assert axis.frame_patch is None and axis.input_patch is axis.global_patch
    in_frame = make_step(model, frame="vessel", axis_radius=2.0).context(x0, nt, mask)
    assert in_frame.global_patch is None and in_frame.input_patch is in_frame.frame_patch
    assert in_frame.frame_patch is not None


def _primitives(jaxpr) -> set[str]:
    """Primitive names in ``jaxpr`` and its sub-jaxprs; the wall search (a ``top_k`` of
    ``WALL_NORMAL_NODES``, the model's radius graph has its own) as ``"wall_search"``."""
    out = set()
    for eqn in jaxpr.eqns:
        out.add(eqn.primitive.name)
        if eqn.primitive.name == "top_k" and eqn.params.get("k") == WALL_NORMAL_NODES:
            out.add("wall_search")
        for sub in jax_core.jaxprs_in_params(eqn.params):
            out |= _primitives(sub)
    return out


def _count(jaxpr, name: str) -> int:
    """Equations of primitive ``name`` in ``jaxpr`` and its sub-jaxprs."""
    return sum((eqn.primitive.name == name)
               + sum(_count(sub, name) for sub in jax_core.jaxprs_in_params(eqn.params))
               for eqn in jaxpr.eqns)


def _scan_bodies(jaxpr):
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "scan":
            yield eqn.params["jaxpr"].jaxpr
        for sub in jax_core.jaxprs_in_params(eqn.params):
            yield from _scan_bodies(sub)


def test_the_rollout_searches_the_wall_once_and_equals_the_step_in_a_loop():
    (x0, x1, _), nt, mask = _frames()
    model = create_model("meshgraphnet", get_config("meshgraphnet", tiny=True))
    step = make_step(model, axis_radius=2.0, prior_radius=2.0)
    params = step.init(jax.random.PRNGKey(1), x0, x1, nt, mask)
    stats = _stats()
    traj = np.asarray(rollout_jit(step, params, stats, x0, x1, nt, mask, 4)[0])
    prev, cur, want = x0, x1, []
    for _ in range(4):
        prev, cur = cur, step(params, stats, prev, cur, nt, mask).positions
        want.append(np.asarray(cur))
    np.testing.assert_allclose(traj, np.stack(want), atol=1e-5)
    assert np.abs(traj[-1] - np.asarray(x1)).max() > 1e-3

    jaxpr = jax.make_jaxpr(lambda p, a, b: _scan(step, p, stats, a, b, nt, mask, 3)[0])(
        params, x0, x1).jaxpr
    bodies = list(_scan_bodies(jaxpr))
    assert bodies and all("wall_search" not in _primitives(b) for b in bodies)
    assert "wall_search" in _primitives(jaxpr)  # made once, before the loop


def test_one_step_computes_the_vessel_axis_once_for_inputs_prior_and_hold():
    """XLA does not merge repeated LAPACK eigh calls inside a loop: the step shares the axis
    (one eigh for the vessel normals, one for the axis), with the same result."""
    (x0, x1, x2), nt, mask = _frames()
    model = create_model("meshgraphnet", get_config("meshgraphnet", tiny=True))
    step = make_step(model, axis_radius=2.0, prior_radius=2.0, lateral_radius=2.0)
    params = step.init(jax.random.PRNGKey(4), x0, x1, nt, mask)
    stats = _stats()
    jaxpr = jax.make_jaxpr(lambda p, a, b: _scan(step, p, stats, a, b, nt, mask, 2)[0])(
        params, x0, x1).jaxpr
    body = next(_scan_bodies(jaxpr))  # the rollout's (the model's own scans come after)
    assert _count(body, "eigh") == 2
    # the parts the step shares it between give what each computes alone
    out = step(params, stats, x1, x2, nt, mask)
    inputs = step.inputs(stats, x1, x2, nt, mask)
    alone = axis_velocity_features(x1, x2, nt, mask, radius=2.0, velocity_scale=0.1)
    np.testing.assert_allclose(np.asarray(inputs.extra), np.asarray(alone), atol=1e-6)
    graph = step.build_graph(inputs)
    accel = _stats().denormalize(model.apply(params, inputs, graph))
    accel = accel - clot_lateral_mean(accel, x2, nt, mask, radius=2.0)
    accel = accel + follow_axis_offset(x1, x2, nt, mask, radius=2.0)
    want = x2 + (x2 - x1) + jnp.where((np.asarray(nt) == NodeType.CLOT)[:, None], accel, 0.0)
    want = jnp.where((np.asarray(nt) == NodeType.CLOT)[:, None], want, x2)
    np.testing.assert_allclose(np.asarray(out.positions), np.asarray(want), atol=1e-5)


def test_the_committee_reads_the_context_too():
    (x0, x1, _), nt, mask = _frames()
    model = create_model("meshgraphnet", get_config("meshgraphnet", tiny=True))
    step = make_step(model, axis_radius=2.0, prior_radius=2.0)
    members = [step.init(jax.random.PRNGKey(k), x0, x1, nt, mask) for k in (2, 3)]
    stats = _stats()
    jaxpr = jax.make_jaxpr(lambda p: _committee_impl(
        step, p, stats, x0, x1, nt, mask, None, 2))(stack_params(members)).jaxpr
    bodies = list(_scan_bodies(jaxpr))
    assert bodies and all("wall_search" not in _primitives(b) for b in bodies)
