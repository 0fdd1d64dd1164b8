"""Host batching: one padding budget, masks, seeded plans, target statistics."""

import numpy as np
import pytest

from thrombojax.data.batching import (
    WindowStore,
    compute_target_stats,
    epoch_plan,
    load_store,
    make_batch,
    padding_budget,
)
from thrombojax.data.scaling import fit_scaling
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset
from thrombojax.types import NodeType


def _sim(name, n_vessel, n_clot, n_frames, seed):
    rng = np.random.default_rng(seed)
    vessel = rng.uniform(-5, 5, (n_vessel, 3))
    clot = rng.normal(0, 1, (n_clot, 3))
    t = np.arange(n_frames)[:, None, None]
    moving = clot[None] + 0.3 * t * np.array([1.0, 0.2, 0.0]) + 0.01 * t**2
    pos = np.concatenate([np.broadcast_to(vessel, (n_frames, n_vessel, 3)), moving], axis=1)
    node_type = np.array([NodeType.VESSEL] * n_vessel + [NodeType.CLOT] * n_clot, np.int8)
    return Simulation(name=name, positions=pos.astype(np.float32), node_type=node_type,
                      attrs={"dt": 1.0})


def _store():
    pos_a = np.random.default_rng(0).normal(size=(6, 10, 3)).astype(np.float32)
    pos_b = np.random.default_rng(1).normal(size=(5, 7, 3)).astype(np.float32)
    types_a = np.array([0] * 6 + [1] * 4, np.int8)
    types_b = np.array([1] * 3 + [0] * 4, np.int8)
    windows = np.array([[0, t] for t in range(1, 5)] + [[1, t] for t in range(1, 4)])
    return WindowStore(("a", "b"), (pos_a, pos_b), (types_a, types_b), windows)


def test_padding_budget():
    assert padding_budget(977) == 1024
    assert padding_budget(27000, 2048) == 2048
    assert padding_budget(100, 2048) == 128
    assert padding_budget(64) == 64


def test_make_batch_pads_and_masks():
    store = _store()
    entries = np.array([[0, 0], [6, 1], [-1, 0]])
    batch = make_batch(store, entries, 64)
    assert batch.frames.shape == (3, 3, 64, 3)
    assert batch.mask[0].sum() == 10 and batch.mask[1].sum() == 7 and batch.mask[2].sum() == 0
    np.testing.assert_array_equal(batch.frames[0, :, :10], store.positions[0][0:3])
    np.testing.assert_array_equal(batch.frames[1, :, :7], store.positions[1][2:5])
    assert np.all(batch.frames[:, :, 10:] == 0) and np.all(batch.node_type[0, 10:] == 0)
    np.testing.assert_array_equal(batch.generated, [False, True, False])
    with pytest.raises(ConfigError):
        make_batch(store, entries, 8)


def test_subsampled_batch_same_nodes_in_all_frames_and_seeded():
    store = _store()
    entries = np.array([[1, 0], [2, 0]])
    a = make_batch(store, entries, 8, nodes_per_sample=5, seed=3, epoch=2, position=4)
    b = make_batch(store, entries, 8, nodes_per_sample=5, seed=3, epoch=2, position=4)
    c = make_batch(store, entries, 8, nodes_per_sample=5, seed=3, epoch=2, position=5)
    np.testing.assert_array_equal(a.frames, b.frames)
    assert not np.array_equal(a.frames, c.frames)
    assert a.mask.sum(1).tolist() == [5, 5]
    full = store.positions[0]
    for s, t in ((0, 2), (1, 3)):  # every frame uses the same node subset
        cols = [np.flatnonzero(np.all(full[t] == a.frames[s, 1, k], axis=1))[0] for k in range(5)]
        np.testing.assert_array_equal(a.frames[s, 0, :5], full[t - 1][cols])
        np.testing.assert_array_equal(a.frames[s, 2, :5], full[t + 1][cols])
        assert (a.node_type[s, :5] == NodeType.CLOT).sum() == 2  # 4 of 10 clot -> 2 of 5


def test_epoch_plan_covers_every_window_once():
    plan = epoch_plan(10, bary_ratio=0.0, batch_size=4, seed=0, epoch=0)
    assert plan.shape == (3, 4, 2)
    flat = plan.reshape(-1, 2)
    np.testing.assert_array_equal(np.sort(flat[flat[:, 0] >= 0, 0]), np.arange(10))
    assert (flat[:, 0] < 0).sum() == 2
    np.testing.assert_array_equal(plan, epoch_plan(10, bary_ratio=0.0, batch_size=4, seed=0,
                                                   epoch=0))
    with pytest.raises(ConfigError):
        epoch_plan(10, bary_ratio=-1.0, batch_size=4, seed=0, epoch=0)


def test_target_stats_match_brute_force():
    store = _store()
    accels = []
    for sim, t in store.windows:
        p = store.positions[sim].astype(np.float64)
        a = p[t + 1] - 2 * p[t] + p[t - 1]
        accels.append(a[store.node_type[sim] == NodeType.CLOT])
    accels = np.concatenate(accels)
    stats = compute_target_stats(store)
    np.testing.assert_allclose(stats.mean, accels.mean(0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(stats.std, accels.std(0), rtol=1e-5)


def test_load_store_scales_and_lists_windows(tmp_path):
    path = write_dataset(tmp_path / "d.h5", [_sim("s0", 30, 10, 6, 0), _sim("s1", 20, 12, 5, 1)],
                         name="synthetic", source="test")
    ds = open_dataset(path)
    scaling = fit_scaling(ds)
    store = load_store(ds, ["s1", "s0"], scaling, skip=2)
    assert store.names == ("s1", "s0") and store.max_nodes == 40
    np.testing.assert_array_equal(store.windows, [[0, 2], [0, 3], [1, 2], [1, 3], [1, 4]])
    np.testing.assert_allclose(store.positions[1], scaling.apply(ds.positions("s0")), atol=1e-5)
    assert np.abs(np.concatenate([p.reshape(-1) for p in store.positions])).max() <= 1.0 + 1e-6


def test_isotropic_stats_for_rotations():
    store = _store()
    per_axis = compute_target_stats(store)
    iso = compute_target_stats(store, isotropic=True)
    np.testing.assert_array_equal(iso.mean, 0.0)
    assert np.allclose(iso.std, iso.std[0])
    second = np.asarray(per_axis.std) ** 2 + np.asarray(per_axis.mean) ** 2
    np.testing.assert_allclose(iso.std[0] ** 2, second.mean(), rtol=1e-5)
