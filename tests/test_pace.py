"""Pace: every clot node's learned step times a factor, before the guards, in every rollout,
and its fit on simulations the model is not measured on."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest
from wall_factory import Outward, straight_tube

from thrombojax.errors import ConfigError
from thrombojax.eval.pace_fit import fit_pace, fit_pace_on_simulations
from thrombojax.models.registry import create_model, identity_stats
from thrombojax.simulator.committee import committee_rollout
from thrombojax.simulator.ensemble import ensemble_rollout, stack_params
from thrombojax.simulator.guard_set import build_guards
from thrombojax.simulator.rollout import guarded_unroll, rollout_with_corrections
from thrombojax.types import NodeType

V = np.float32([0.05, 0.0, 0.0])  # the clot's velocity along the tube at the start
N_STEPS = 10


def _start():
    """A clot gliding along the middle of a straight tube (constant velocity: no guard acts)."""
    x0, node_type = straight_tube()
    clot = node_type == NodeType.CLOT
    x_prev = x0 - np.where(clot[:, None], V, 0.0).astype(np.float32)
    return x_prev, x0, node_type, clot


def _centroid_path(traj, x0, clot):
    return np.asarray(traj)[:, clot, 0].mean(axis=1) - x0[clot, 0].mean()


def test_pace_scales_each_step_of_the_rollout():
    """Constant velocity with pace p: every step is p times the last, so after k steps the clot
    has moved v (p + p^2 + ... + p^k); without pace (or with p = 1) k v. Only clot rows move,
    and the correction recorded is how far pace moved each node."""
    x_prev, x0, node_type, clot = _start()
    model, stats, mask = create_model("constant_velocity"), identity_stats(), np.ones(len(x0), bool)
    paths, corrections = {}, {}
    for pace in (None, 1.0, 0.5, 1.2):
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, pace=pace)
        traj, corr = rollout_with_corrections(model, {}, stats, x_prev, x0, node_type, mask,
                                              N_STEPS, guards=guards)
        paths[pace] = _centroid_path(traj, x0, clot)
        corrections[pace] = {k: np.asarray(v) for k, v in corr.items()}
        np.testing.assert_array_equal(np.asarray(traj)[:, ~clot], np.broadcast_to(
            x0[~clot], (N_STEPS, (~clot).sum(), 3)))
    k = np.arange(1, N_STEPS + 1)
    np.testing.assert_allclose(paths[None], k * V[0], rtol=1e-4)
    np.testing.assert_allclose(paths[1.0], paths[None], rtol=1e-5)
    for pace in (0.5, 1.2):
        expected = V[0] * np.cumsum(pace ** k)
        np.testing.assert_allclose(paths[pace], expected, rtol=1e-4)
        moved = corrections[pace]["pace"]
        step = np.abs(pace - 1.0) * V[0] * pace ** (k - 1)  # the learned step was v p^(k-1)
        np.testing.assert_allclose(moved[:, clot], np.broadcast_to(step[:, None], (N_STEPS,
                                                                               clot.sum())),
                                   rtol=1e-3)
        assert moved[:, ~clot].max() == 0.0
    assert "pace" not in corrections[None]
    assert corrections[1.0]["pace"].max() == 0.0


def test_pace_in_ensembles_acts_on_each_member_and_the_committee_once():
    """An ensemble paces each member's own steps and not their averaged output again; a
    committee paces its mean step: two identical members match the single model's path."""
    x_prev, x0, node_type, clot = _start()
    model, stats, mask = create_model("constant_velocity"), identity_stats(), np.ones(len(x0), bool)
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0, pace=0.5)
    single, _ = rollout_with_corrections(model, {}, stats, x_prev, x0, node_type, mask, N_STEPS,
                                         guards=guards)
    stacked = stack_params([{"w": jnp.zeros(1)}, {"w": jnp.zeros(1)}])
    ens = ensemble_rollout(model, stacked, stats, x_prev, x0, node_type, mask, N_STEPS,
                           rollout_fn=guarded_unroll, context=guards, guard_mean=True)
    com = committee_rollout(model, stacked, stats, x_prev, x0, node_type, mask, N_STEPS,
                            guards=guards)
    want = _centroid_path(single, x0, clot)
    np.testing.assert_allclose(want, V[0] * np.cumsum(0.5 ** np.arange(1, N_STEPS + 1)),
                               rtol=1e-4)  # paced once per step, not twice
    np.testing.assert_allclose(_centroid_path(ens.mean, x0, clot), want, rtol=1e-5)
    np.testing.assert_allclose(_centroid_path(com.mean, x0, clot), want, rtol=1e-5)
    assert "pace" not in ens.mean_corrections  # the mean is guarded, not paced again


@pytest.mark.parametrize("pace", [0.0, -1.0, float("nan"), float("inf")])
def test_a_pace_that_is_not_a_positive_number_is_refused(pace):
    x0, node_type = straight_tube()
    with pytest.raises(ConfigError, match="pace must be a number > 0"):
        build_guards(x0, node_type, x0, node_type, radius=1.0, pace=pace)


def test_fit_pace_finds_the_pace_where_the_clot_ends_on_the_true_one():
    """A clot whose along-track error grows with the pace as a model's does: the ratio guess and
    secant steps find the root within the tolerance; a root beyond the bounds stops there."""
    calls = []

    def along_at(pace):  # the model's clot travels 1.25 times the true 40 r at pace 1
        calls.append(pace)
        return 40.0 * (1.25 * pace * (1.0 + 0.1 * (pace - 1.0)) - 1.0)

    fit = fit_pace(along_at, 40.0, tol_r=0.01)
    assert abs(fit["along_r"]) <= 0.01 and len(calls) <= 4 and calls[0] == 1.0
    assert fit["pace"] == pytest.approx(calls[-1]) and fit["pace"] < 0.85
    assert [p for p, _ in fit["evaluations"]] == calls
    far = fit_pace(lambda pace: 40.0 * (5.0 * pace - 1.0), 40.0, bounds=(0.5, 2.0))
    assert far["pace"] == 0.5 and len(far["evaluations"]) == 2  # pinned at the lower bound
    assert fit_pace(lambda pace: 0.0, 40.0)["evaluations"] == [[1.0, 0.0]]
    with pytest.raises(ConfigError, match="does not move along its track"):
        fit_pace(along_at, 0.0)
    with pytest.raises(ConfigError, match="bounds"):
        fit_pace(along_at, 40.0, bounds=(1.1, 2.0))


@dataclasses.dataclass(frozen=True)
class Cruise(Outward):
    """A surrogate whose every node moves ``u`` along the tube per step, whatever its velocity
    (as a model that reads its speed from the vessel, not from its last step)."""

    u: float = 0.05
    name: str = "cruise"

    def apply(self, params, inputs, graph, *, train=False, rng=None):
        return jnp.asarray([self.u, 0.0, 0.0]) - inputs.velocity  # identity statistics


def test_fit_pace_on_simulations_recovers_the_true_speed_over_the_models():
    """The true clot glides 0.03 per frame, the model's 0.05: the fitted pace is 0.6 and the
    clot then ends on the true one."""
    x0, node_type = straight_tube(half_length=3.0)
    clot = node_type == NodeType.CLOT
    frames = np.arange(30, dtype=np.float32)[:, None, None] * np.where(
        clot[:, None], np.float32([0.03, 0.0, 0.0]), 0.0)
    positions = (x0[None] - np.float32([1.0, 0.0, 0.0]) * clot[:, None] + frames)
    fit = fit_pace_on_simulations(Cruise(), {}, identity_stats(),
                                  [("tube", positions.astype(np.float32), node_type, None)],
                                  radius=1.0, t0=1, n_nodes=None, ensemble=False)
    assert fit["pace"] == pytest.approx(0.6, rel=1e-3)
    assert abs(fit["along_r"]) < 1e-3 and fit["evaluations"][0][1] > 0.5  # ahead at pace 1
    assert fit["simulations"] == ["tube"]
    assert fit["track_length_r"] == pytest.approx(28 * 0.03, rel=1e-4)
