"""Memory a training flag asks for (issue 14): the estimate bounds what the loop's buffers take
(tracemalloc for the epoch plan, the arrays of a batch, XLA's memory analysis for the triangle
search), and a configuration that cannot fit is one line naming the option and both numbers."""

from __future__ import annotations

import functools
import tracemalloc

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import accelerating_sims

from thrombojax.cli import main
from thrombojax.data.augment import AugmentConfig, augment_batch
from thrombojax.data.batching import Batch, epoch_plan, load_store, make_batch, padding_budget
from thrombojax.data.scaling import fit_scaling
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import open_dataset, write_dataset
from thrombojax.train.config import TrainConfig
from thrombojax.train.memory import (
    PLAN_BYTES_PER_ENTRY,
    available_memory,
    check_train_memory,
    estimate_train_memory,
)


def estimate(**kw):
    base = dict(n_windows=10, n_val_windows=0, bary_ratio=0.0, batch_size=4, budget=64,
                length=3, max_neighbors=16)
    return estimate_train_memory(**{**base, **kw})


@pytest.mark.parametrize("n_windows,bary_ratio,batch_size", [(1000, 50.0, 8), (7, 3000.0, 3)])
def test_plan_estimate_bounds_the_measured_peak(n_windows, bary_ratio, batch_size):
    tracemalloc.start()
    try:
        plan = epoch_plan(n_windows, bary_ratio=bary_ratio, batch_size=batch_size, seed=0,
                          epoch=0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    est = estimate(n_windows=n_windows, bary_ratio=bary_ratio, batch_size=batch_size)
    assert est["epoch plan"] == PLAN_BYTES_PER_ENTRY * plan.shape[0] * plan.shape[1]
    # one plan's peak, plus the previous epoch's plan (16 bytes per entry) held meanwhile
    assert peak + plan.nbytes <= est["epoch plan"] <= 1.2 * (peak + plan.nbytes)


def test_batch_estimate_is_the_arrays_of_a_batch(tmp_path):
    data = write_dataset(tmp_path / "d.h5", accelerating_sims(n_sims=2, n_nodes=60, n_frames=6),
                         name="d", source="t")
    ds = open_dataset(data)
    store = load_store(ds, list(ds.names), fit_scaling(ds), length=3)
    budget = padding_budget(store.max_nodes)
    plan = epoch_plan(len(store), bary_ratio=0.0, batch_size=4, seed=0, epoch=0)
    batch = make_batch(store, plan[0], budget)
    one = sum(np.asarray(getattr(batch, f)).nbytes for f in ("frames", "node_type", "mask",
                                                              "generated"))
    est = estimate(n_windows=len(store), n_val_windows=9, batch_size=4, budget=budget)
    assert est["batches"] == (3 + 3) * one  # 3 validation batches + host, device, augmented
    assert est["triangle search"] == 0  # no BaryCentricSampling


@pytest.mark.parametrize("n_nodes,k,batch_size", [(256, 16, 2)])
def test_triangle_estimate_bounds_what_xla_allocates(n_nodes, k, batch_size):
    cfg = AugmentConfig(max_rotation=np.pi, barycentric=True, radius=0.5, max_neighbors=k)
    fn = jax.jit(functools.partial(augment_batch, config=cfg))
    batch = Batch(frames=jnp.zeros((batch_size, 3, n_nodes, 3)),
                  node_type=jnp.zeros((batch_size, n_nodes), jnp.int32),
                  mask=jnp.ones((batch_size, n_nodes), bool),
                  generated=jnp.ones((batch_size,), bool))
    mem = fn.lower(jax.random.PRNGKey(0), batch).compile().memory_analysis()
    xla = mem.temp_size_in_bytes + mem.output_size_in_bytes
    est = estimate(bary_ratio=1.0, batch_size=batch_size, budget=n_nodes, max_neighbors=k)
    assert xla <= est["triangle search"] <= 2 * xla


def test_check_refuses_naming_option_and_both_numbers():
    est = estimate(n_windows=100, bary_ratio=1e6)  # plan: 96 bytes x 1e8 entries = 9.6 GB
    check_train_memory(est, values={"bary_ratio": 1e6}, available=10**11)  # fits in 100 GB
    with pytest.raises(ConfigError) as err:
        check_train_memory(est, values={"bary_ratio": 1e6}, where="d.h5", available=10**9)
    msg = str(err.value)
    assert msg.startswith("d.h5: --bary-ratio") and "bary_ratio 1e+06" in msg
    assert f"about {sum(est.values()) / 1e9:.3g} GB" in msg and msg.endswith("available 1 GB")
    with pytest.raises(ConfigError, match="bary_max_neighbors"):
        check_train_memory(estimate(bary_ratio=1.0, max_neighbors=4096), values={},
                           available=10**9)


def test_config_refuses_what_cannot_fit_even_on_one_window():
    assert available_memory() and available_memory() > 10**8
    TrainConfig(bary_ratio=2.0)  # the study's value fits
    with pytest.raises(ConfigError, match=r"--bary-ratio .* available"):
        TrainConfig(bary_ratio=1e13)  # 96 bytes x 1e13 entries: 960 TB
    with pytest.raises(ConfigError, match="bary_max_neighbors"):
        TrainConfig(bary_ratio=1.0, bary_max_neighbors=100_000)


def test_cli_train_refuses_with_the_dataset_sizes(tmp_path, capsys):
    """A ratio that fits one window passes the option check; on the dataset's 16 training
    windows (the study recipe's 3-frame windows) it cannot fit: one line, exit 2, before any
    compilation or output file."""
    data = write_dataset(tmp_path / "d.h5", accelerating_sims(n_sims=4, n_nodes=60, n_frames=6),
                         name="d", source="t")
    ratio = available_memory() / PLAN_BYTES_PER_ENTRY / 4  # one window: a quarter of memory
    TrainConfig(bary_ratio=ratio)
    run = tmp_path / "run"
    code = main(["train", "--dataset", str(data), "--model", "mgn", "--out", str(run), "--tiny",
                 "--n-val", "1", "--bary-ratio", repr(ratio), "--recipe", "study", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert f"{data}: --bary-ratio" in err and "available" in err
    assert not (run / "config.json").exists()
