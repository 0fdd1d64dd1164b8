"""One-step error of a deep ensemble: the member mean's error, one member = the plain error."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from dataset_factory import accelerating_sims

from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import mse_per_step
from thrombojax.eval.single_step import ensemble_single_step_errors, single_step_errors
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.types import TargetStats, clot_mask


@pytest.fixture(scope="module")
def case():
    sim = accelerating_sims(n_sims=1, n_nodes=64, n_frames=7)[0]
    pos = np.asarray(sim.positions, np.float32) / 10.0
    nt = np.asarray(sim.node_type, np.int32)
    step = make_step(create_model("mgn", get_config("mgn", tiny=True)))
    mask = np.ones(len(nt), bool)
    params = [step.init(jax.random.key(k), pos[0], pos[1], nt, mask) for k in (0, 1)]
    stats = TargetStats(mean=np.zeros(3, np.float32), std=np.full(3, 0.05, np.float32),
                        velocity_std=np.float32(0.01))
    return step, params, stats, pos, nt


def test_one_member_is_the_plain_error(case):
    step, params, stats, pos, nt = case
    np.testing.assert_array_equal(
        ensemble_single_step_errors(step, params[:1], stats, pos, nt, batch_size=3),
        single_step_errors(step, params[0], stats, pos, nt, batch_size=3))


def test_two_members_score_their_mean_prediction(case):
    step, params, stats, pos, nt = case
    got = ensemble_single_step_errors(step, params, stats, pos, nt, skip=2, batch_size=2)
    mask = np.ones(len(nt), bool)
    want = []
    for t in range(2, pos.shape[0] - 1):
        preds = [np.asarray(step(p, stats, pos[t - 1], pos[t], nt, mask).positions)
                 for p in params]
        want.append(mse_per_step(np.mean(preds, axis=0)[None], pos[t + 1][None],
                                 clot_mask(nt))[0])
    np.testing.assert_allclose(got, want, rtol=1e-5)
    # the members differ, so the mean is not either member's prediction
    alone = [single_step_errors(step, p, stats, pos, nt, skip=2, batch_size=2) for p in params]
    assert not np.allclose(got, alone[0]) and not np.allclose(got, alone[1])


def test_no_member_is_an_error(case):
    step, _, stats, pos, nt = case
    with pytest.raises(ConfigError, match="at least one member"):
        ensemble_single_step_errors(step, [], stats, pos, nt)
