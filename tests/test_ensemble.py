"""Ensembles: M rollouts in one compiled program, spread-versus-error measures, trained members."""

from __future__ import annotations

import json
import shutil

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import TRACES, FakeSurrogate, accelerating_sims, rollout_state

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.eval.uncertainty import (
    CURVE_KEYS,
    node_errors,
    uncertainty_curves,
    uncertainty_report,
    uncertainty_summary,
)
from thrombojax.simulator.ensemble import (
    ensemble_jit,
    ensemble_rollout,
    ensemble_stats,
    stack_params,
    stochastic_rollout,
)
from thrombojax.simulator.rollout import rollout
from thrombojax.types import NodeType


def _state(n=40, seed=0):
    return rollout_state(n, seed)


def _params(model, seed):
    return model.init(jax.random.key(seed), None, None)


def test_identical_members_give_the_single_rollout_and_zero_spread():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    p = _params(model, 0)
    single = np.asarray(rollout(model, p, stats, x_prev, x_cur, node_type, mask, 6))
    ens = ensemble_rollout(model, stack_params([p, p, p]), stats, x_prev, x_cur, node_type,
                           mask, 6)
    assert ens.members.shape == (3, 6, 40, 3) and ens.n_members == 3
    assert ens.mean.shape == (6, 40, 3) and ens.spread.shape == (6, 40)
    assert np.array_equal(np.asarray(ens.mean), single)
    assert np.array_equal(np.asarray(ens.spread), np.zeros((6, 40)))


def test_different_members_spread_on_clot_only_and_members_are_their_rollouts():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    plist = [_params(model, s) for s in (0, 1, 2)]
    ens = ensemble_rollout(model, stack_params(plist), stats, x_prev, x_cur, node_type, mask, 5)
    members = np.asarray(ens.members)
    for i, p in enumerate(plist):  # member i is the rollout of params i
        np.testing.assert_allclose(
            members[i], np.asarray(rollout(model, p, stats, x_prev, x_cur, node_type, mask, 5)),
            rtol=0, atol=1e-5)
    clot = (node_type == NodeType.CLOT) & mask
    spread = np.asarray(ens.spread)
    assert (spread[:, clot] > 0).all()
    assert np.array_equal(spread[:, ~clot], np.zeros((5, int((~clot).sum()))))
    assert np.array_equal(np.asarray(ens.mean)[:, ~clot],
                          np.broadcast_to(x_cur[~clot], (5, int((~clot).sum()), 3)))
    # spread = sqrt(trace(population covariance) / 3)
    want = np.sqrt(members.astype(np.float64).var(axis=0).mean(axis=-1))
    np.testing.assert_allclose(spread[:, clot], want[:, clot], rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(np.asarray(ens.mean), members.mean(0), rtol=0, atol=1e-6)


def test_compiled_once_for_all_members():
    model = FakeSurrogate(radius=0.45)  # a step of its own: its own compilations
    x_prev, x_cur, node_type, mask, stats = _state()
    TRACES.clear()
    size0 = ensemble_jit._cache_size()
    stack = stack_params([_params(model, s) for s in range(4)])
    ens = ensemble_rollout(model, stack, stats, x_prev, x_cur, node_type, mask, 4)
    assert len(TRACES) == 1 and ensemble_jit._cache_size() == size0 + 1
    stack2 = stack_params([_params(model, s) for s in range(4, 8)])
    ens2 = ensemble_rollout(model, stack2, stats, x_prev + 0.1, x_cur + 0.1, node_type, mask, 4)
    assert len(TRACES) == 1 and ensemble_jit._cache_size() == size0 + 1
    assert not np.allclose(np.asarray(ens.mean), np.asarray(ens2.mean))


def test_stochastic_rollout_perturbs_clot_starts_only():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    p = _params(model, 0)
    kw = dict(n_members=5, noise_std=1e-3, rng=jax.random.key(3))
    ens = stochastic_rollout(model, p, stats, x_prev, x_cur, node_type, mask, 4, **kw)
    again = stochastic_rollout(model, p, stats, x_prev, x_cur, node_type, mask, 4, **kw)
    assert np.array_equal(np.asarray(ens.members), np.asarray(again.members))
    assert ens.members.shape == (5, 4, 40, 3)
    clot = (node_type == NodeType.CLOT) & mask
    spread = np.asarray(ens.spread)
    assert (spread[:, clot] > 0).all() and (spread[:, ~clot] == 0).all()
    single = np.asarray(rollout(model, p, stats, x_prev, x_cur, node_type, mask, 4))
    assert np.abs(np.asarray(ens.mean) - single)[:, clot].max() < 0.05
    # stacked members plus perturbed starts: M starts, one per member
    both = ensemble_rollout(model, stack_params([p, p]), stats, x_prev, x_cur, node_type, mask,
                            4, noise_std=1e-3, rng=jax.random.key(0))
    assert (np.asarray(both.spread)[:, clot] > 0).all()
    with pytest.raises(ConfigError):
        stochastic_rollout(model, p, stats, x_prev, x_cur, node_type, mask, 4, n_members=3,
                           noise_std=0.0, rng=jax.random.key(0))
    with pytest.raises(ConfigError):
        ensemble_rollout(model, stack_params([p]), stats, x_prev, x_cur, node_type, mask, 4,
                         noise_std=1e-3)
    with pytest.raises(ConfigError):
        ensemble_rollout(model, stack_params([p]), stats, x_prev, x_cur, node_type, mask, 0)


def test_stack_params_refuses_different_trees():
    a = {"w": jnp.ones((3, 3)), "b": jnp.zeros(3)}
    stacked = stack_params([a, a])
    assert stacked["w"].shape == (2, 3, 3) and stacked["b"].shape == (2, 3)
    with pytest.raises(ConfigError, match="member 1 .*'w'"):
        stack_params([a, {"w": jnp.ones((3, 4)), "b": jnp.zeros(3)}])
    with pytest.raises(ConfigError, match="member 2"):
        stack_params([a, a, {"w": jnp.ones((3, 3))}])
    with pytest.raises(ConfigError):
        stack_params([])


def test_ensemble_stats_exact_zero_for_equal_members():
    x = jnp.asarray(np.random.default_rng(0).normal(size=(1, 5, 7, 3)), jnp.float32) * 1e3 + 0.1
    mean, spread = ensemble_stats(jnp.repeat(x, 3, axis=0))
    assert np.array_equal(np.asarray(mean), np.asarray(x[0]))
    assert np.array_equal(np.asarray(spread), np.zeros((5, 7)))


def _constructed(factor: float, n_steps=4, n=30, seed=0):
    """Mean, spread, truth with per-node error exactly ``factor * spread`` on clot nodes."""
    rng = np.random.default_rng(seed)
    mean = rng.normal(size=(n_steps, n, 3))
    spread = rng.uniform(0.1, 1.0, (n_steps, n))
    truth = mean + factor * spread[..., None] * rng.choice([-1.0, 1.0], size=(n_steps, n, 3))
    node_type = np.full(n, NodeType.CLOT)
    node_type[::4] = NodeType.VESSEL
    truth[:, node_type == NodeType.VESSEL] += 50.0  # never counted
    return mean, spread, truth, node_type


def test_uncertainty_metrics_on_constructed_errors():
    mean, spread, truth, node_type = _constructed(1.5)
    clot = node_type == NodeType.CLOT
    np.testing.assert_allclose(node_errors(mean, truth)[:, clot], 1.5 * spread[:, clot])
    curves = uncertainty_curves(mean, spread, truth, node_type, scale=2.0)
    assert set(curves) == set(CURVE_KEYS) and all(v.shape == (4,) for v in curves.values())
    np.testing.assert_allclose(curves["spearman"], 1.0)
    np.testing.assert_allclose(curves["pearson"], 1.0)
    np.testing.assert_allclose(curves["calibration"], 1.5)
    np.testing.assert_allclose(curves["rms_calibration"], 1.5)
    np.testing.assert_allclose(curves["within_2_spread"], 1.0)
    np.testing.assert_allclose(curves["error"], 2.0 * 1.5 * spread[:, clot].mean(1))
    summary = uncertainty_summary(mean, spread, truth, node_type)
    assert summary["spearman"] == pytest.approx(1.0) and summary["calibration"] == \
        pytest.approx(1.5)
    assert summary["within_2_spread"] == 1.0 and summary["n_clot_nodes"] == int(clot.sum())
    json.dumps(summary, allow_nan=False)
    # errors three times the spread: none within 2 spreads; a mask drops padded nodes
    mask = np.ones(30, bool)
    mask[-5:] = False
    curves3, summary3 = uncertainty_report(*_constructed(3.0), mask=mask)
    assert (curves3["within_2_spread"] == 0).all() and summary3["calibration"] == \
        pytest.approx(3.0)
    assert summary3["n_clot_nodes"] == int((clot & mask).sum())
    # error unrelated to spread in rank: reversed ranks give -1
    mean, spread, truth, node_type = _constructed(1.0)
    rev = mean + (1.1 - spread)[..., None]
    assert uncertainty_curves(mean, spread, rev, node_type)["spearman"] == \
        pytest.approx(np.full(4, -1.0))


def test_uncertainty_undefined_values_are_null_in_json():
    mean, spread, truth, node_type = _constructed(1.0)
    zero = np.zeros_like(spread)
    curves = uncertainty_curves(mean, zero, truth, node_type)
    assert np.isnan(curves["spearman"]).all() and np.isinf(curves["calibration"]).all()
    summary = uncertainty_summary(mean, zero, truth, node_type)
    assert summary["spearman"] is None and summary["calibration"] is None
    json.dumps(summary, allow_nan=False)
    with pytest.raises(DatasetError):
        uncertainty_curves(mean, spread[:, :5], truth, node_type)
    with pytest.raises(DatasetError):
        uncertainty_curves(mean, spread, truth, np.full(30, NodeType.VESSEL))


@pytest.fixture(scope="module")
def tiny_ensemble(tmp_path_factory):
    from thrombojax.io.hdf5 import write_dataset
    from thrombojax.train.ensemble import train_ensemble

    root = tmp_path_factory.mktemp("ensemble")
    sims = accelerating_sims(n_nodes=96, n_frames=8, scale=10.0)
    data = write_dataset(root / "tiny.h5", sims, name="tiny-ens", source="test")
    ens = train_ensemble(data, "mgn", root / "ens", 2, seed=3, epochs=1, tiny=True, n_val=1,
                         batch_size=2, warmup_epochs=0, progress=False)
    return data, root, ens


def test_train_and_load_ensemble(tiny_ensemble):
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.train.ensemble import load_ensemble

    data, root, ens = tiny_ensemble
    assert ens.n_members == 2 and ens.seeds == [3, 4]
    assert [d.name for d in ens.directories] == ["member_0", "member_1"]
    assert json.loads((root / "ens" / "ensemble.json").read_text())["seeds"] == [3, 4]
    w = jax.tree.leaves(ens.params)
    assert all(x.shape[0] == 2 for x in w)
    assert any(not np.allclose(np.asarray(x[0]), np.asarray(x[1])) for x in w)
    loaded = load_ensemble(root / "ens", which="last")
    assert loaded.stats.to_dict() == ens.stats.to_dict() and loaded.n_members == 2
    # the loaded ensemble rolls out on the dataset: members disagree on clot nodes only
    sim = open_dataset(data)["sim_0"]
    frames = np.asarray(ens.scaling.apply(sim.positions), np.float32)
    mask = np.ones(sim.node_type.shape[0], bool)
    out = ensemble_rollout(ens.model, ens.params, ens.stats, frames[3], frames[4],
                           sim.node_type, mask, 3)
    clot = sim.node_type == NodeType.CLOT
    assert (np.asarray(out.spread)[:, clot] > 0).all() and (np.asarray(out.spread)[:, ~clot]
                                                             == 0).all()
    # a real model, two copies of member 0 (same compiled program): batched kernels may round
    # differently from a single rollout, but agreeing members give their value exactly, spread 0
    p0 = jax.tree.map(lambda x: x[0], ens.params)
    same = ensemble_rollout(ens.model, stack_params([p0, p0]), ens.stats, frames[3], frames[4],
                            sim.node_type, mask, 3)
    assert np.array_equal(np.asarray(same.mean), np.asarray(same.members[0]))
    assert np.array_equal(np.asarray(same.spread), np.zeros_like(np.asarray(same.spread)))
    np.testing.assert_allclose(np.asarray(same.mean), np.asarray(out.members[0]), rtol=0,
                               atol=1e-5)


def _edit_config(run_dir, edit):
    path = run_dir / "config.json"
    config = json.loads(path.read_text())
    edit(config)
    path.write_text(json.dumps(config))


def test_load_ensemble_refuses_mismatched_members(tiny_ensemble):
    from thrombojax.train.ensemble import load_ensemble

    _, root, _ = tiny_ensemble
    cases = {
        "scaling": lambda c: c["scaling"].update(scale=c["scaling"]["scale"] * 2),
        "statistics": lambda c: c["stats"].update(velocity_std=c["stats"]["velocity_std"] * 2),
        "model config": lambda c: c["train"]["model_config"].update(max_neighbors=6),
    }
    for what, edit in cases.items():
        bad = root / f"bad_{what.replace(' ', '_')}"
        shutil.copytree(root / "ens", bad)
        _edit_config(bad / "member_1", edit)
        with pytest.raises(ConfigError, match=f"member_1: ensemble member differs from "
                                              f"member_0 in {what};") as err:
            load_ensemble(bad)
        assert "\n" not in str(err.value)
    empty = root / "empty"
    empty.mkdir()
    with pytest.raises(ConfigError, match="not an ensemble"):
        load_ensemble(empty)
    partial = root / "partial"
    shutil.copytree(root / "ens", partial)
    shutil.rmtree(partial / "member_1" / "checkpoints")
    with pytest.raises(ConfigError, match="member_1: ensemble member has no 'best'"):
        load_ensemble(partial)


def _clamped_unroll(step, params, stats, x0_prev, x0, node_type, mask, n_steps, context):
    """A custom member rollout: the plain one clipped to a box (the context), plus how far."""
    from thrombojax.simulator.ensemble import plain_unroll

    pos = plain_unroll(step, params, stats, x0_prev, x0, node_type, mask, n_steps, None)
    clipped = jnp.clip(pos, -context, context)
    return clipped, jnp.abs(clipped - pos).max(axis=-1)


def test_member_chunks_and_custom_member_rollout():
    model = FakeSurrogate()
    x_prev, x_cur, node_type, mask, stats = _state()
    stack = stack_params([_params(model, s) for s in range(3)])
    whole = ensemble_rollout(model, stack, stats, x_prev, x_cur, node_type, mask, 5)
    chunked = ensemble_rollout(model, stack, stats, x_prev, x_cur, node_type, mask, 5,
                               member_batch=2)
    np.testing.assert_allclose(np.asarray(chunked.members), np.asarray(whole.members),
                               rtol=0, atol=1e-6)
    p = _params(model, 0)
    kw = dict(n_members=3, noise_std=1e-3, rng=jax.random.key(1))
    a = stochastic_rollout(model, p, stats, x_prev, x_cur, node_type, mask, 5, **kw)
    b = stochastic_rollout(model, p, stats, x_prev, x_cur, node_type, mask, 5, member_batch=1,
                           **kw)
    np.testing.assert_allclose(np.asarray(b.members), np.asarray(a.members), rtol=0, atol=1e-6)
    box = 0.5
    guarded = ensemble_rollout(model, stack, stats, x_prev, x_cur, node_type, mask, 5,
                               rollout_fn=_clamped_unroll, context=jnp.float32(box))
    assert np.abs(np.asarray(guarded.members)).max() <= box
    assert guarded.aux.shape == (3, 5, 40) and float(guarded.aux.max()) > 0
    np.testing.assert_allclose(np.asarray(guarded.members),
                               np.clip(np.asarray(whole.members), -box, box), atol=1e-6)
    with pytest.raises(ConfigError):
        ensemble_rollout(model, stack, stats, x_prev, x_cur, node_type, mask, 5, member_batch=0)


def _fixed_frames(step, params, stats, x_prev, x0, node_type, mask, n_steps, context):
    """A member 'rollout' that holds the member's own frame ``params['x']`` for every step."""
    del step, stats, x_prev, x0, node_type, mask, context
    return jnp.broadcast_to(params["x"], (n_steps, *params["x"].shape))


def test_guard_mean_puts_the_mean_of_two_members_in_a_bend_back_inside():
    """Two members inside a bent vessel (a unit tube on a circle of radius 4), one clot 45
    degrees before the middle of the bend and one 45 degrees after: their mean cuts the corner
    and lies outside (guard_mean off); the guarded mean is inside, its correction is recorded,
    and members, spread and vessel nodes are untouched."""
    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.simulator.walls import fraction_outside_wall

    def on_bend(phi, radial, z):  # the point at bend angle phi, radial and z off the axis
        r = 4.0 + radial
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)

    phi, ang = np.meshgrid(np.linspace(-np.pi / 2, np.pi / 2, 61),
                           np.linspace(0, 2 * np.pi, 24, endpoint=False))
    wall = on_bend(phi.ravel(), np.cos(ang.ravel()), np.sin(ang.ravel()))
    rng = np.random.default_rng(0)
    blob = rng.uniform(-0.3, 0.3, (20, 3))
    clot_a = on_bend(-np.pi / 4 + blob[:, 0] / 4, blob[:, 1], blob[:, 2])
    clot_b = on_bend(np.pi / 4 + blob[:, 0] / 4, blob[:, 1], blob[:, 2])
    node_type = np.array([NodeType.CLOT] * 20 + [NodeType.VESSEL] * len(wall), np.int32)
    xa = np.concatenate([clot_a, wall]).astype(np.float32)
    xb = np.concatenate([clot_b, wall]).astype(np.float32)
    mask = np.ones(len(xa), bool)
    a, q = np.meshgrid(np.arange(24), np.arange(60), indexing="ij")  # the wall's triangles
    corner = lambda da, dq: 20 + ((a + da) % 24) * 61 + q + dq  # noqa: E731
    cells = np.concatenate([np.stack([corner(0, 0), corner(0, 1), corner(1, 1)], -1),
                            np.stack([corner(0, 0), corner(1, 1), corner(1, 0)], -1)])
    guards = build_guards(xa, node_type, xa, node_type, radius=1.0, coherence=False,
                          wall_cells=cells.reshape(-1, 3))
    stack = stack_params([{"x": jnp.asarray(xa)}, {"x": jnp.asarray(xb)}])
    stats = rollout_state(8)[-1]
    kw = dict(rollout_fn=_fixed_frames, context=guards)
    free = ensemble_rollout(FakeSurrogate(), stack, stats, xa, xa, node_type, mask, 3, **kw)
    held = ensemble_rollout(FakeSurrogate(), stack, stats, xa, xa, node_type, mask, 3,
                            guard_mean=True, **kw)
    clot = jnp.asarray(node_type == NodeType.CLOT)

    def outside(frames):
        return max(float(fraction_outside_wall(jnp.asarray(f), clot, guards.wall))
                   for f in frames)

    assert outside(free.members[0]) == 0.0 and outside(free.members[1]) == 0.0
    assert outside(free.mean) > 0.9 and outside(held.mean) == 0.0
    assert free.mean_corrections is None
    moved = np.asarray(held.mean_corrections["containment"])
    assert moved.shape == (3, len(xa)) and moved[:, :20].max() > 0.1 and moved[:, 20:].max() == 0
    np.testing.assert_array_equal(np.asarray(held.mean)[:, 20:], np.asarray(free.mean)[:, 20:])
    np.testing.assert_array_equal(np.asarray(held.members), np.asarray(free.members))
    np.testing.assert_array_equal(np.asarray(held.spread), np.asarray(free.spread))
    with pytest.raises(ConfigError, match="guard_mean needs"):
        ensemble_rollout(FakeSurrogate(), stack, stats, xa, xa, node_type, mask, 3,
                         rollout_fn=_fixed_frames, guard_mean=True)


def test_join_ensemble_of_runs_trained_one_by_one(tiny_ensemble, tmp_path, capsys):
    """Runs trained apart join into an ensemble folder that loads as the trained ensemble; the
    runs are not touched, and every mistake is refused before anything is written."""
    from thrombojax.cli import main
    from thrombojax.train.ensemble import join_ensemble, load_ensemble

    _, root, ens = tiny_ensemble
    runs = [root / "ens" / "member_0", root / "ens" / "member_1"]
    before = {p: p.read_bytes() for r in runs for p in sorted(r.rglob("*")) if p.is_file()}
    joined = join_ensemble(runs, tmp_path / "joined", which="last")
    manifest = json.loads((tmp_path / "joined" / "ensemble.json").read_text())
    assert manifest["members"] == [str(r.resolve()) for r in runs] and manifest["seeds"] == [3, 4]
    assert joined.seeds == [3, 4] and list(joined.directories) == [r.resolve() for r in runs]
    again, trained = load_ensemble(tmp_path / "joined"), load_ensemble(root / "ens")
    for a, b in zip(jax.tree.leaves(again.params), jax.tree.leaves(trained.params), strict=True):
        assert np.array_equal(np.asarray(a), np.asarray(b))
    assert {p: p.read_bytes() for r in runs for p in sorted(r.rglob("*")) if p.is_file()} == before
    # mistakes: each refused, nothing written
    bad = root / "join_bad_scaling"
    shutil.copytree(runs[1], bad)
    _edit_config(bad, lambda c: c["scaling"].update(scale=c["scaling"]["scale"] * 2))
    cases = [([runs[0]], "two or more runs"), ([runs[0], runs[0]], "listed twice"),
             ([runs[0], tmp_path], "not a training run"), ([runs[0], bad], "differs from "
                                                           "/.*/ens/member_0 in scaling")]
    for i, (given, match) in enumerate(cases):
        with pytest.raises(ConfigError, match=match):
            join_ensemble(given, tmp_path / f"refused_{i}")
        assert not (tmp_path / f"refused_{i}").exists()
    with pytest.raises(ConfigError, match="inside the run"):
        join_ensemble(runs, runs[0] / "ens")
    with pytest.raises(ConfigError, match="trained ensemble members"):
        join_ensemble(runs, root / "ens")
    with pytest.raises(ConfigError, match="exists; pass force"):
        join_ensemble(runs[::-1], tmp_path / "joined")
    assert json.loads((tmp_path / "joined" / "ensemble.json").read_text()) == manifest
    assert join_ensemble(runs[::-1], tmp_path / "joined", force=True).seeds == [4, 3]
    twin = root / "join_twin"
    shutil.copytree(runs[0], twin)
    with pytest.warns(UserWarning, match="same seed 3"):
        join_ensemble([runs[0], twin], tmp_path / "twins")
    # the command line: the same join, then refused without --force (exit 2, one line)
    capsys.readouterr()
    out = tmp_path / "cli"
    assert main(["ensemble", str(runs[0]), str(runs[1]), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "joined 2 mgn runs (seeds 3, 4)" in said and f"--run {out}" in said
    assert main(["ensemble", str(runs[0]), str(runs[1]), "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
