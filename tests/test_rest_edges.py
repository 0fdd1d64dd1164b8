"""Rest-state edge displacements: a step with ``rest_edges`` reads the clot's rest state (the
simulation's first frame) at the head of its ``x_prev`` (:mod:`thrombojax.simulator.previous`)
and MeshGraphNet's clot-clot edges get their rest displacement beside the current one."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.graph.neighbors import radius_graph
from thrombojax.models.meshgraphnet import edge_features
from thrombojax.models.registry import create_model, get_config, identity_stats
from thrombojax.simulator.flat import flat_batch_ok
from thrombojax.simulator.rollout import unroll
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType


def _mgn(**kw):
    return create_model("mgn", get_config("mgn", tiny=True, max_neighbors=8, radius=0.45, **kw))


def _scene(seed=0, n_clot=30, frames=6):
    """A trajectory ``[T, N, 3]``: a random clot cloud stretched a little more each frame as it
    moves along x, beside a ring of 16 vessel nodes, 2 padded nodes last."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    ring = np.stack([np.zeros(16), 1.2 * np.cos(ang), 1.2 * np.sin(ang)], axis=1)
    clot = rng.normal(size=(n_clot, 3)) * 0.3
    nt = np.array([NodeType.VESSEL] * 16 + [NodeType.CLOT] * n_clot + [NodeType.VESSEL] * 2,
                  np.int32)
    mask = np.arange(len(nt)) < 16 + n_clot
    out = []
    for t in range(frames):
        c = clot * np.array([1 + 0.03 * t, 1, 1]) + [0.05 * t, 0, 0]
        out.append(np.concatenate([ring, c, np.zeros((2, 3))]))
    return np.asarray(out, np.float32), nt, mask


@pytest.mark.parametrize("history", [1, 3])
def test_previous_leads_with_the_rest_frame_and_shift_keeps_it(history):
    pos, nt, mask = _scene()
    step = make_step(_mgn(), history=history, rest_edges=True)
    prev = np.asarray(step.previous(pos, 4))
    want = [pos[max(4 - j, 0)] for j in range(history, 0, -1)]
    np.testing.assert_array_equal(prev, np.stack([pos[0], *want]))
    # an explicit rest frame (a training window starts later), and arrays of frames
    window = pos[2:]
    np.testing.assert_array_equal(np.asarray(step.previous(window, history, pos[0]))[0], pos[0])
    many = np.asarray(step.previous(pos, np.array([1, 5])))
    assert many.shape == (2, 1 + history, len(nt), 3)
    np.testing.assert_array_equal(many[:, 0], np.stack([pos[0], pos[0]]))
    np.testing.assert_array_equal(np.asarray(step.last_previous(prev)), pos[3])
    nxt = np.asarray(step.shift(jnp.asarray(prev), jnp.asarray(pos[4])))
    np.testing.assert_array_equal(nxt, np.asarray(step.previous(pos, 5)))
    step.check_previous(prev, len(nt), "test")
    with pytest.raises(ConfigError, match="rest frame"):
        step.check_previous(prev[1:], len(nt), "test")


def test_edge_features_add_the_rest_displacement_on_clot_clot_edges_only():
    pos, nt, mask = _scene()
    x, rest = jnp.asarray(pos[3]), jnp.asarray(pos[0])
    clot = jnp.asarray((nt == NodeType.CLOT) & mask)
    graph = radius_graph(x, 0.45, 8, mask=jnp.asarray(mask))
    plain = np.asarray(edge_features(x, graph))
    both = np.asarray(edge_features(x, graph, rest, clot))
    assert plain.shape[1] == 4 and both.shape[1] == 8
    np.testing.assert_array_equal(both[:, :4], plain)
    idx = np.asarray(graph.indices)
    n, k = idx.shape
    for i in range(n):
        for s in range(k):
            j, e = idx[i, s], both[i * k + s, 4:]
            if j < n and clot[i] and clot[j]:
                np.testing.assert_allclose(e[:3], pos[0][i] - pos[0][j], atol=1e-6)
                np.testing.assert_allclose(e[3], np.linalg.norm(pos[0][i] - pos[0][j]),
                                           rtol=1e-5)
            else:
                assert not e.any()


def test_the_step_reads_the_rest_state_and_a_rollout_carries_it():
    """Another rest state changes the step's output; a rollout keeps the rest frame it started
    with (its steps equal single steps with ``x_prev`` from ``previous`` on the predicted
    trajectory); models without edge features and flat batches refuse the option."""
    pos, nt, mask = _scene()
    step = make_step(_mgn(), rest_edges=True)
    params = step.init(jax.random.key(0), step.previous(pos, 1), pos[1], nt, mask)
    stats = identity_stats()
    out = step(params, stats, step.previous(pos, 3), pos[3], nt, mask).output
    other = step(params, stats, step.previous(pos, 3, pos[1]), pos[3], nt, mask).output
    assert float(jnp.abs(out - other).max()) > 1e-4
    traj, _ = unroll(step, params, stats, step.previous(pos, 2), pos[2], nt, mask, 3)
    full = np.concatenate([pos[:3], np.asarray(traj)])
    for i in range(3):
        one = step(params, stats, step.previous(full, 2 + i), full[2 + i], nt, mask).positions
        np.testing.assert_allclose(np.asarray(traj[i]), np.asarray(one), atol=1e-5)
    assert not flat_batch_ok(step)
    with pytest.raises(ConfigError, match="rest_edges"):
        make_step(create_model("transolver", get_config("transolver", tiny=True)),
                  rest_edges=True)


def test_batches_lead_with_the_rest_frame_of_the_same_nodes():
    """``make_batch(..., rest=True)``: every window led by its simulation's frame 0, of the
    same subsampled nodes (here node ``i`` of frame ``t`` sits at ``(i, t, 0)``)."""
    from dataset_factory import numbered_store

    from thrombojax.data.batching import make_batch

    store = numbered_store(7)
    entries = np.array([[2, 0], [4, 0]])
    plain = make_batch(store, entries, 64, nodes_per_sample=20, seed=1)
    rest = make_batch(store, entries, 64, nodes_per_sample=20, seed=1, rest=True)
    assert rest.frames.shape[1] == plain.frames.shape[1] + 1
    np.testing.assert_array_equal(rest.frames[:, 1:], plain.frames)
    real = plain.mask
    np.testing.assert_array_equal(rest.frames[:, 0, :, 0][real], plain.frames[:, 0, :, 0][real])
    assert not rest.frames[:, 0, :, 1].any()  # frame 0
    assert (plain.frames[:, 0, :, 1][real] > 0).all()  # the windows start later


def test_rest_edges_let_a_model_see_and_take_back_a_stretch():
    """Fails without the rest state: on random clouds of nodes the tiny model trained with
    stretch noise (600 Adam steps) keeps a stretch it is given (0.98 when written); reading each
    edge's rest length it takes back about two fifths of it (0.60)."""
    from dataset_factory import ring_clot_window, stretch_carry_after_training
    from test_speed_noise import STATS

    def carry(rest: bool) -> float:
        step = make_step(_mgn(), rest_edges=rest)
        return stretch_carry_after_training(step, ring_clot_window, STATS, stretch_noise=0.3,
                                            steps=600)

    assert carry(False) > 0.9
    assert carry(True) < 0.8


def test_cli_trains_with_rest_edges_reloads_the_step_and_rolls_out(tmp_path):
    from dataset_factory import train_tiny_cli

    from thrombojax.cli import main
    from thrombojax.train.checks import check_train_values
    from thrombojax.train.config import TrainConfig
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--rest-edges", n_nodes=80)
    loaded = load_trained(run)
    assert loaded.run.train.rest_edges is True and loaded.step.rest_edges
    assert loaded.params["params"]["edge_encoder"]["dense_0"]["kernel"].shape[0] == 8
    out = tmp_path / "ro"
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--split", "test", "--no-gif", "--quiet"]) == 0
    assert (out / "rollout.json").exists()
    with pytest.raises(ConfigError, match="rest_edges"):
        check_train_values(TrainConfig(rest_edges="yes"))
