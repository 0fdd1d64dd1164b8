"""The vessel-following prior: the step moves the clot along the vessel's axis at its speed."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_vessel_axis import _tube

from thrombojax.errors import ConfigError
from thrombojax.graph.vessel_axis import follow_axis_offset, vessel_axis
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.step import make_step
from thrombojax.train.loss import window_loss_terms
from thrombojax.types import NodeType


def _experiment():
    """``experiments/follow_axis.py`` loaded as a module (it is a script, not a package)."""
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).resolve().parents[1] / "experiments" / "follow_axis.py"
    spec = importlib.util.spec_from_file_location("follow_axis", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _bent(seed=1):
    """A unit tube bent on a circle of radius 4, clot near its axis at the bend's start."""
    big = 4.0
    return _tube(lambda s: big * np.array([np.sin(s / big), 1.0 - np.cos(s / big), 0.0]),
                 lambda s: np.array([np.cos(s / big), np.sin(s / big), 0.0]),
                 np.random.default_rng(seed), n_wall=1500, half_length=6.0)


def test_the_offset_turns_the_velocity_onto_the_axis_at_its_speed():
    x, nt, _ = _bent()
    clot = nt == NodeType.CLOT
    mask = jnp.ones(len(nt), bool)
    v = np.where(clot[:, None], [0.1, 0.03, 0.02], 0.0).astype(np.float32)
    u = np.asarray(follow_axis_offset(jnp.asarray(x - v), jnp.asarray(x), jnp.asarray(nt),
                                      mask, radius=2.0))
    t = np.asarray(vessel_axis(jnp.asarray(x), jnp.asarray(nt), mask, radius=2.0))
    moved = (v + u)[clot]
    np.testing.assert_allclose(np.linalg.norm(moved, axis=1), np.linalg.norm(v[clot], axis=1),
                               rtol=1e-4)
    assert np.abs(np.cross(moved, t[clot])).max() < 1e-5  # along the axis
    assert (np.sum(moved * v[clot], axis=1) > 0).all()  # forward, not back
    assert not u[~clot].any()
    at_rest = follow_axis_offset(jnp.asarray(x), jnp.asarray(x), jnp.asarray(nt), mask,
                                 radius=2.0)
    assert float(jnp.abs(at_rest).max()) < 1e-12
    grad = jax.grad(lambda p: follow_axis_offset(p, jnp.asarray(x), jnp.asarray(nt), mask,
                                                 radius=2.0).sum())(jnp.asarray(x))
    assert bool(jnp.isfinite(grad).all())  # defined at rest
    no_vessel = np.full(len(nt), NodeType.CLOT, np.int32)
    assert not np.asarray(follow_axis_offset(jnp.asarray(x - v), jnp.asarray(x),
                                             jnp.asarray(no_vessel), mask, radius=2.0)).any()


def test_the_step_adds_the_prior_and_the_loss_learns_what_it_leaves():
    """Constant velocity (zero model output) with the prior follows the bend; on a window whose
    truth is that prior the loss is 0, and it is not without the prior."""
    x, nt, _ = _bent()
    clot = nt == NodeType.CLOT
    mask = jnp.ones(len(nt), bool)
    v = np.where(clot[:, None], [0.1, 0.0, 0.0], 0.0).astype(np.float32)
    cv = create_model("constant_velocity")
    follow, plain = make_step(cv, prior_radius=2.0), make_step(cv)
    stats = identity_stats()
    nxt = np.asarray(follow({}, stats, jnp.asarray(x - v), jnp.asarray(x), nt, mask).positions)
    u = np.asarray(follow_axis_offset(jnp.asarray(x - v), jnp.asarray(x), jnp.asarray(nt), mask,
                                      radius=2.0))
    np.testing.assert_allclose(nxt, x + v + u, atol=1e-6)
    assert np.abs(u[clot]).max() > 1e-3  # the bend turns it
    frames = jnp.asarray(np.stack([x - v, x, nxt]))
    kw = dict(train=False, rng=None)
    assert float(window_loss_terms(follow, {}, stats, frames, nt, mask, **kw)["loss_sum"]) < 1e-10
    assert float(window_loss_terms(plain, {}, stats, frames, nt, mask, **kw)["loss_sum"]) > 1e-6
    with pytest.raises(ConfigError, match="prior_radius"):
        make_step(cv, prior_radius=-1.0)


def test_the_follow_axis_experiment_rules_and_script(tmp_path):
    """experiments/follow_axis.py: per node keeps each speed along the axis, rigid moves the
    clot as one body, 'axis part only' drops the speed across; the script writes its table
    with the environment (and the room rules with --room-fit) and refuses to replace it
    without --force."""
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.sim.generate import generate_dataset

    module = _experiment()
    t = jnp.asarray([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    v = jnp.asarray([[-0.3, 0.4, 0.0], [0.1, 0.2, 0.0], [0.5, 0.5, 0.5]])
    clot = jnp.asarray([True, True, False])
    per_node = np.asarray(module.next_velocity("axis speed, per node", v, t, clot))
    np.testing.assert_allclose(per_node[:2], [[-0.5, 0, 0], [0, np.sqrt(0.05), 0]], atol=1e-6)
    assert not per_node[2].any()
    rigid = np.asarray(module.next_velocity("axis speed, rigid", v, t, clot))
    np.testing.assert_allclose(rigid[0], rigid[1])
    np.testing.assert_allclose(np.linalg.norm(rigid[0]), np.linalg.norm([-0.1, 0.3, 0.0]),
                               rtol=1e-5)
    part = np.asarray(module.next_velocity("axis part only", v, t, clot))
    np.testing.assert_allclose(part[:2], [[-0.3, 0, 0], [0, 0.2, 0]], atol=1e-6)
    # the script, with the room rules of --room-fit (test below) fitted on the other simulation
    data = generate_dataset("clotentry-tiny", tmp_path / "ce.h5", n_sims=2, seed=3,
                            progress=False)
    fit, name = open_dataset(data).names
    out = tmp_path / "follow"
    argv = ["--dataset", str(data), "--sims", name, "--room-fit", fit, "--out", str(out)]
    assert module.main(argv) == 0
    text = (out / "table.md").read_text()
    assert "axis speed, per node, guarded" in text and "- jax:" in text
    assert "room speed, rigid, guarded" in text and f"fitted on {fit}" in text
    with pytest.raises(Exception, match="exists|force"):
        module.main(argv)
    # the flat line: the fitted simulation's mean speed, no slope, rows named for what they are
    a, b = module.fit_room_line(open_dataset(data), [fit], constant=True)
    slope_a, slope_b = module.fit_room_line(open_dataset(data), [fit])
    assert b == 0.0 and slope_b != 0.0 and 0.0 < a
    flat = tmp_path / "flat"
    assert module.main(argv[:-1] + [str(flat), "--room-line", "constant"]) == 0
    text = (flat / "table.md").read_text()
    assert "training pace, per node, guarded" in text and "room speed" not in text
    assert f"Training pace: speed = {a:.4f} + 0.0000" in text
    with pytest.raises(SystemExit):  # a flat line with nothing to fit it on
        module.main(["--dataset", str(data), "--sims", name, "--room-line", "constant",
                     "--out", str(tmp_path / "no_fit")])
    with pytest.raises(SystemExit):  # a scored simulation is not fitted on
        module.main(["--dataset", str(data), "--sims", name, "--room-fit", name,
                     "--out", str(tmp_path / "refused")])


def test_the_room_rules_move_at_the_fitted_speed_from_the_clearance():
    """experiments/follow_axis.py's room rules: the speed is a + b * (centroid to nearest wall
    node), per node along each node's signed axis, rigid along the clot's mean axis; a room
    rule without a speed is refused (the script's --room-fit: the test above)."""
    module = _experiment()
    x = jnp.asarray([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [9.0, 9.0, 9.0]])
    clot = jnp.asarray([True, True, False])
    wall = jnp.asarray([[1.0, 3.0, 0.0], [1.0, -5.0, 0.0]])  # centroid (1, 0, 0): clearance 3
    speed = module.room_speed(x, clot, wall, (0.2, 0.1), radius=2.0)
    assert float(speed) == pytest.approx(2.0 * 0.2 + 0.1 * 3.0)
    t = jnp.asarray([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    v = jnp.asarray([[-0.3, 0.4, 0.0], [0.1, 0.2, 0.0], [0.5, 0.5, 0.5]])
    per_node = np.asarray(module.next_velocity("room speed, per node", v, t, clot, speed))
    np.testing.assert_allclose(per_node, [[-0.7, 0, 0], [0, 0.7, 0], [0, 0, 0]], atol=1e-6)
    rigid = np.asarray(module.next_velocity("room speed, rigid", v, t, clot, speed))
    np.testing.assert_allclose(rigid[0], rigid[1])
    np.testing.assert_allclose(np.linalg.norm(rigid[0]), 0.7, rtol=1e-5)
    assert not rigid[2].any()
    with pytest.raises(ValueError, match="needs a speed"):
        module.next_velocity("room speed, rigid", v, t, clot)
