"""The batch as one flat graph (``thrombojax/simulator/flat.py``) equals ``jax.vmap`` over samples.

Loss, metrics and gradients of :func:`thrombojax.train.step.batch_loss` with ``flat_batch=True``
against the vmapped form, on a tiny one-block MeshGraphNet (perturbed parameters, so every term
matters), samples of different sizes and padding; with training noise, the k-step and
push-forward losses, the vessel frame, wall features, the vessel-following prior and the lateral
hold; one optimiser step of the train step; and the models that are not graph-local keep the
vmapped form.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import clot_acceleration_stats, synthetic_window
from tree_helpers import TOL, assert_trees_close, perturbed

from thrombojax.data.batching import Batch
from thrombojax.errors import ConfigError
from thrombojax.graph.neighbors import NeighborList
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.flat import FlatStep, flat_batch_ok, flatten_graphs
from thrombojax.simulator.step import make_step
from thrombojax.train.schedule import make_optimizer
from thrombojax.train.step import batch_loss, init_state, make_train_step

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

N_FRAMES = 5  # s_t-1 .. s_t+3: enough for k = 2 after one push-forward step


def _batch(size=3):
    """Windows of different clots and padding (same padded size), extended to 5 frames."""
    windows = []
    for s in range(size):
        frames, node_type, mask = synthetic_window(s, n_clot=18 + 3 * s, n_pad=10 - 3 * s)
        while len(frames) < N_FRAMES:  # constant acceleration, plus a per-node wiggle
            nxt = 3 * frames[-1] - 3 * frames[-2] + frames[-3]
            frames = np.concatenate([frames, nxt[None] + 0.002 * np.sin(frames[-1])[None]])
        windows.append((frames.astype(np.float32), node_type, mask))
    return Batch(frames=np.stack([w[0] for w in windows]),
                 node_type=np.stack([w[1] for w in windows]),
                 mask=np.stack([w[2] for w in windows]), generated=np.zeros(size, bool))


def _setup(name="mgn", **step_options):
    # MeshGraphNet with one message-passing block: a node that read another sample's nodes
    # (or missed its own) changes the loss after one block as after two, at a cheaper compile
    overrides = {"processor_size": 1} if name == "mgn" else {}
    model = create_model(name, get_config(name, tiny=True, **overrides))
    batch = _batch()
    step = make_step(model, **step_options)
    state = init_state(step, make_optimizer(1e-3), jax.random.PRNGKey(0), batch)
    return step, perturbed(state.params), clot_acceleration_stats(batch), batch


def _loss_and_grads(step, params, stats, batch, flat, **options):
    def loss(p):
        return batch_loss(step, p, stats, batch, jax.random.PRNGKey(3), flat_batch=flat,
                          **options)

    return jax.jit(jax.value_and_grad(loss, has_aux=True))(params)


def _assert_same(step, params, stats, batch, **options):
    (l_vmap, m_vmap), g_vmap = _loss_and_grads(step, params, stats, batch, False, **options)
    (l_flat, m_flat), g_flat = _loss_and_grads(step, params, stats, batch, True, **options)
    assert np.isfinite(float(l_vmap)) and float(l_vmap) > 0
    np.testing.assert_allclose(l_flat, l_vmap, rtol=TOL, atol=TOL)
    for key in ("mse", "nodes"):
        np.testing.assert_allclose(m_flat[key], m_vmap[key], rtol=TOL, atol=1e-12)
    assert_trees_close(g_flat, g_vmap)
    assert max(float(jnp.abs(x).max()) for x in jax.tree.leaves(g_vmap)) > 1e-3


@pytest.mark.parametrize("options", [
    {"train": True, "noise_std": 0.01, "noise_gamma": 0.25},
    {"train": False},
    {"train": True, "noise_std": 0.01, "k": 2, "pushforward": 1},
    {"train": True, "noise_std": 0.01, "noise_shared": 0.5},
], ids=["noise", "eval", "k2-pushforward", "shared-noise"])
def test_flat_equals_vmap_loss_and_gradients(options):
    _assert_same(*_setup(), **options)


@pytest.mark.parametrize("options", [
    {"train": True, "noise_std": 0.01},
    {"train": True, "noise_std": 0.01, "k": 2, "pushforward": 1},
], ids=["one-step", "k2-pushforward"])
def test_flat_equals_vmap_in_the_vessel_frame_with_wall_features_prior_and_lateral_hold(options):
    """The k-step loss unrolls the flat step with its rollout context (one per sample, the
    vessel-axis search in the vessel's frame and in the global one)."""
    _assert_same(*_setup(frame="vessel", wall_cutoff=0.3, axis_radius=1.0, prior_radius=1.0,
                         lateral_radius=1.0), **options)


def test_flat_graph_offsets_samples_and_keeps_sentinels():
    step, _, stats, batch = _setup()
    frames = jnp.asarray(batch.frames)
    def graph(p, c, t, m):
        return step.build_graph(step.inputs(stats, p, c, t, m))

    graphs = jax.jit(jax.vmap(graph))(frames[:, 0], frames[:, 1], jnp.asarray(batch.node_type),
                                      jnp.asarray(batch.mask))
    flat = jax.jit(flatten_graphs)(graphs)
    b, n, k = graphs.indices.shape
    ids = np.asarray(flat.indices).reshape(b, n, k)
    per = np.asarray(graphs.indices)
    real = per < n
    assert real.any() and (~real).any()
    owner = np.arange(b)[:, None, None]
    np.testing.assert_array_equal(ids[real], (per + owner * n)[real])  # own sample only
    assert np.all(ids[~real] == b * n)
    np.testing.assert_array_equal(np.asarray(flat.counts), np.asarray(graphs.counts).ravel())
    overflowed = NeighborList(graphs.indices, graphs.counts, jnp.array([False, True, False]))
    assert bool(flatten_graphs(overflowed).overflow) and not bool(flat.overflow)


def test_one_train_step_is_the_same_flat_or_vmapped():
    step, params, stats, batch = _setup()
    tx = make_optimizer(1e-3, grad_clip=1.0)
    states = {}
    for flat in (False, True):
        state = init_state(step, tx, jax.random.PRNGKey(0), batch).replace(params=params)
        train_step = make_train_step(step, tx, stats, noise_std=0.01, donate=False,
                                     flat_batch=flat)
        states[flat], metrics = train_step(state, batch, jax.random.PRNGKey(1))
        assert np.isfinite(float(metrics["grad_norm"]))
    assert_trees_close(states[True].params, states[False].params)
    assert not np.allclose(jax.tree.leaves(states[False].params)[0], jax.tree.leaves(params)[0])


@pytest.mark.parametrize("name", ["transolver", "erwin"])
def test_models_that_mix_a_sample_keep_the_vmapped_form(name):
    step, params, stats, batch = _setup(name)
    assert not flat_batch_ok(step)
    with pytest.raises(ConfigError, match="vmap"):
        FlatStep(step)
    losses = [jax.jit(lambda p, f=flat: batch_loss(step, p, stats, batch, None, train=False,
                                                   flat_batch=f)[0])(params)
              for flat in (False, True)]
    np.testing.assert_array_equal(losses[1], losses[0])
