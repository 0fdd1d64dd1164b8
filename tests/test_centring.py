"""The centring guard: the clot's centroid held near the middle of the vessel's cross-section."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from wall_factory import Outward, bent_vessel, straight_tube

from thrombojax.errors import ConfigError
from thrombojax.simulator.centring import centre_clot, section_centre
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.guards import wall_from_simulation
from thrombojax.simulator.rollout import rollout_with_corrections
from thrombojax.types import NodeType, TargetStats

LENGTHS = {"axis_radius": 2.0, "slab": 0.5, "reach": 3.0}  # the guard's, for a unit radius


def _tube_wall():
    x0, node_type = straight_tube()
    return x0, node_type, wall_from_simulation(x0, node_type, None)


def test_the_centre_of_a_tube_is_on_its_axis():
    _, _, wall = _tube_wall()
    for point in ([0.3, 0.5, 0.0], [-0.5, -0.2, 0.6], [0.0, 0.0, 0.0]):
        centre, axis, ok = section_centre(jnp.asarray(point, jnp.float32), wall, **LENGTHS)
        assert bool(ok)
        np.testing.assert_allclose(np.asarray(centre), [point[0], 0.0, 0.0], atol=0.03)
        assert abs(float(axis[0])) > 0.99


def test_the_centre_follows_a_bend():
    """On the bent tube's triangles, points off its centreline are brought back to it."""
    vessel = bent_vessel()
    wall = wall_from_simulation(vessel["positions"], vessel["node_type"], vessel["wall_cells"])
    cl = np.asarray(vessel["centreline"].points)  # spaced 0.1
    errors_before, errors_after = [], []
    for i in range(len(cl) // 3, 2 * len(cl) // 3, max(len(cl) // 12, 1)):
        tangent = cl[i + 1] - cl[i - 1]
        side = np.cross(tangent, [0.0, 0.0, 1.0])
        side /= np.linalg.norm(side)  # in the bend's plane, across the vessel
        point = cl[i] + 0.5 * side
        centre, _, ok = section_centre(jnp.asarray(point, jnp.float32), wall, **LENGTHS)
        assert bool(ok)
        distance = np.linalg.norm(cl - np.asarray(centre), axis=1).min()
        errors_before.append(np.linalg.norm(cl - point, axis=1).min())
        errors_after.append(distance)
    assert max(errors_after) < 0.12 < 0.4 < min(errors_before)


def test_centre_clot_moves_the_clot_rigidly_to_the_tolerance():
    x0, node_type, wall = _tube_wall()
    clot = x0[node_type == NodeType.CLOT]
    shifted = clot + np.float32([0.0, 0.4, 0.3])  # centroid ~0.5 off the axis
    f = jax.jit(lambda y: centre_clot(y, wall, tolerance=0.2, **LENGTHS))
    x_new, corr = map(np.asarray, f(jnp.asarray(shifted)))
    offset = np.linalg.norm(x_new.mean(axis=0)[1:])
    assert offset == pytest.approx(0.2, abs=0.02)
    move = x_new - shifted
    np.testing.assert_allclose(move, np.broadcast_to(move[0], move.shape), atol=1e-6)
    np.testing.assert_allclose(corr, np.linalg.norm(move[0]), rtol=1e-5)
    assert move[0, 0] == pytest.approx(0.0, abs=1e-3)  # across the axis only
    same, none = map(np.asarray, f(jnp.asarray(clot)))  # within the tolerance: untouched
    np.testing.assert_array_equal(same, clot)
    np.testing.assert_array_equal(none, 0.0)


def test_no_centre_past_an_open_end():
    _, _, wall = _tube_wall()  # the tube ends at x = +-2
    _, _, ok = section_centre(jnp.asarray([2.6, 0.4, 0.0], jnp.float32), wall, **LENGTHS)
    assert not bool(ok)
    clot = (np.random.default_rng(1).normal(0, 0.1, (20, 3)) + [2.6, 0.4, 0]).astype(np.float32)
    x_new, corr = centre_clot(jnp.asarray(clot), wall, tolerance=0.1, **LENGTHS)
    np.testing.assert_array_equal(np.asarray(x_new), clot)
    np.testing.assert_array_equal(np.asarray(corr), 0.0)


@dataclasses.dataclass(frozen=True)
class Sideways(Outward):
    """A surrogate that accelerates every node across the tube (+y), 0.02 per step."""

    name: str = "sideways"

    def apply(self, params, inputs, graph, *, train=False, rng=None):
        return jnp.broadcast_to(jnp.asarray([0.0, 0.02, 0.0]), inputs.positions.shape)


def _lateral_offsets(traj, node_type):
    return np.linalg.norm(np.asarray(traj)[:, node_type == NodeType.CLOT].mean(axis=1)[:, 1:],
                          axis=-1)


def test_centring_holds_a_drifting_clot_in_the_middle_of_the_rollout():
    """A model that drifts the clot sideways: with centring its centroid stays within the
    tolerance of the axis, without it (containment alone) the clot is pressed to the wall."""
    x0, node_type = straight_tube()
    mask = np.ones(len(x0), bool)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.ones(3))
    run = {}
    for label, centring in (("off", None), ("on", 0.2)):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, coherence=False,
                              centring_r=centring)
        traj, corr = rollout_with_corrections(Sideways(), {}, stats, x0, x0, node_type, mask,
                                              12, guards=guards)
        run[label] = (_lateral_offsets(traj, node_type), {k: np.asarray(v)
                                                          for k, v in corr.items()})
    assert run["off"][0].max() > 0.5 and set(run["off"][1]) == {"containment"}
    assert run["on"][0].max() < 0.21
    assert set(run["on"][1]) == {"centring", "containment"}
    moved = run["on"][1]["centring"]
    assert moved[:, node_type == NodeType.CLOT].max() > 0.0
    assert moved[:, node_type != NodeType.CLOT].max() == 0.0


def test_a_negative_centring_tolerance_is_refused():
    x0, node_type = straight_tube()
    with pytest.raises(ConfigError, match="centring tolerance"):
        build_guards(x0, node_type, x0, node_type, radius=1.0, centring_r=-0.1)


def _tube_sim(offsets):
    """A straight-tube 'simulation' whose clot's centroid lies ``offsets[t]`` off the axis in
    frame t (the clot moved sideways rigidly), plus each frame's true offset."""
    from types import SimpleNamespace

    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    x0[clot] -= np.float32([0.0, *x0[clot].mean(axis=0)[1:]])  # the clot's centroid on the axis
    frames = np.repeat(x0[None], len(offsets), axis=0)
    frames[:, clot, 1] += np.float32(offsets)[:, None]
    truth = np.linalg.norm(frames[:, clot].mean(axis=1)[:, 1:], axis=-1)
    return SimpleNamespace(positions=frames, node_type=node_type, wall_cells=None), truth


def test_fit_centring_is_the_quantile_of_the_true_offsets():
    """The tolerance fitted on a set of simulations is the chosen quantile of their clots'
    offsets from the middle: small where the clots keep to the middle, wide where they run
    along the wall (then the guard hardly acts); no usable frame is an error."""
    from types import SimpleNamespace

    from thrombojax.errors import DatasetError
    from thrombojax.eval.centring_fit import centroid_offsets, fit_centring

    middle, truth_a = _tube_sim(np.linspace(0.0, 0.1, 21))
    wall_hugging, truth_b = _tube_sim(np.linspace(0.3, 0.6, 21))
    offset, ok = centroid_offsets(middle.positions, middle.node_type, None, 1.0)
    assert ok.all()
    np.testing.assert_allclose(offset, truth_a, atol=0.03)
    sims = {"a": middle, "b": wall_hugging}
    ds = type("DS", (), {"path": "fake.h5", "__getitem__": lambda self, n: sims[n]})()
    fit = fit_centring(ds, ["a"], 1.0)
    assert fit["frames"] == 21 and fit["simulations"] == ["a"] and fit["quantile"] == 0.95
    assert abs(fit["centring_r"] - np.quantile(truth_a, 0.95)) < 0.03
    both = fit_centring(ds, ["a", "b"], 1.0, quantile=0.5)
    assert abs(both["centring_r"] - np.quantile(np.r_[truth_a, truth_b], 0.5)) < 0.03
    assert fit_centring(ds, ["b"], 1.0)["centring_r"] > 0.5 > 0.12 > fit["centring_r"]
    # scale: the same tube twice as large, radius 2: the same tolerance in radii
    big = SimpleNamespace(positions=middle.positions * 2, node_type=middle.node_type,
                          wall_cells=None)
    ds_big = type("DS", (), {"path": "big.h5", "__getitem__": lambda self, n: big})()
    assert abs(fit_centring(ds_big, ["a"], 2.0)["centring_r"] - fit["centring_r"]) < 1e-4
    with pytest.raises(DatasetError, match="fake.h5: no simulations"):
        fit_centring(ds, [], 1.0)
    with pytest.raises(DatasetError, match="quantile"):
        fit_centring(ds, ["a"], 1.0, quantile=0.0)
    off_end = SimpleNamespace(positions=middle.positions + np.float32([5.0, 0, 0]) *
                              (middle.node_type == NodeType.CLOT)[:, None],
                              node_type=middle.node_type, wall_cells=None)
    ds_end = type("DS", (), {"path": "end.h5", "__getitem__": lambda self, n: off_end})()
    with pytest.raises(DatasetError, match="end.h5: simulations a: no frame"):
        fit_centring(ds_end, ["a"], 1.0)
