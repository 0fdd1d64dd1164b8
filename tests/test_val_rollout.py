"""Checkpoints picked by the validation rollout (``--select-by rollout``,
:mod:`thrombojax.train.validation`): logged per epoch, the best checkpoint is the lowest rollout
MSE, the metrics are those of the evaluation, the training itself is unchanged; and by the last
epoch (``--select-by last``)."""

import json

import jax
import numpy as np
import pytest
from test_train_loop import SMALL, _params, _simulation

from thrombojax.cli import main
from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import centroid_error, mse_per_step
from thrombojax.eval.rollouts import rollout_simulation
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.io.hdf5 import open_dataset, write_dataset
from thrombojax.train.config import TrainConfig
from thrombojax.train.loop import train
from thrombojax.train.plots import best_epoch
from thrombojax.train.state import load_trained
from thrombojax.train.summary import run_summary
from thrombojax.train.validation import (
    VAL_ROLLOUT_KEYS,
    epoch_score,
    prepare_val_rollouts,
    val_rollout_metrics,
)

RUN = dict(SMALL, epochs=3, max_rotation=0.0)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "synthetic.h5"
    return write_dataset(path, [_simulation(i, n_frames=8) for i in range(5)], name="synthetic",
                         source="test")


@pytest.fixture(scope="module")
def runs(dataset, tmp_path_factory):
    """The same run picking its best checkpoint by one-step MSE, by the rollout, by the end."""
    root = tmp_path_factory.mktemp("runs")
    train(dataset, "mgn", root / "mse", progress=False, **RUN)
    for how in ("rollout", "last"):
        code = main(["train", "--dataset", str(dataset), "--model", "mgn", "--out",
                     str(root / how), "--config", str(_config(root, RUN)), "--select-by", how,
                     "--quiet"])
        assert code == 0
    return root / "mse", root / "rollout", root / "last"


def _config(root, values):
    path = root / "cfg.json"
    path.write_text(json.dumps(values))
    return path


def _records(run):
    return [json.loads(ln) for ln in (run / "metrics.jsonl").read_text().splitlines()]


def test_rollout_logged_and_picks_the_best_checkpoint(runs):
    by_mse, by_rollout, _ = runs
    records = _records(by_rollout)
    assert [r["epoch"] for r in records] == [1, 2, 3]
    for r in records:
        assert all(np.isfinite(r[k]) for k in VAL_ROLLOUT_KEYS), r
        assert r["val_rollout_cv_ratio"] > 0 and r["val_rollout_mse_r2"] > 0
    assert not any("val_rollout_mse" in r for r in _records(by_mse))
    best = min(records, key=lambda r: r["val_rollout_mse"])
    assert _params(by_rollout, "best")[1]["epoch"] == best["epoch"]
    assert best_epoch(records)[:1] == (best["epoch"],)
    text = run_summary(by_rollout, "mgn")
    assert f"best validation rollout MSE {best['val_rollout_mse']:.4g} at epoch " \
        f"{best['epoch']}" in text and "constant-velocity" in text
    assert (by_rollout / "loss.png").is_file()


def _same_params(a, b):
    a, b = (jax.tree.leaves(jax.tree.map(np.asarray, p)) for p in (a, b))
    return all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_training_is_unchanged_by_the_rollouts(runs):
    """Validation rollouts use no random key: the last parameters are bit-for-bit the same."""
    by_mse, by_rollout, _ = runs
    assert _same_params(_params(by_mse)[0], _params(by_rollout)[0])
    for r1, r2 in zip(_records(by_mse), _records(by_rollout), strict=True):
        assert r1["train_loss"] == r2["train_loss"] and r1["val_mse"] == r2["val_mse"]


def test_select_by_last_keeps_the_last_epoch(runs):
    by_mse, _, by_last = runs
    records = _records(by_last)
    params, meta = _params(by_last, "best")
    assert meta["epoch"] == 3 and _same_params(params, _params(by_last)[0])
    assert _same_params(params, _params(by_mse)[0])  # the same training
    assert best_epoch(records, "last") == (3, records[-1]["val_mse"], "val_mse")
    assert "best checkpoint: the last epoch (3, --select-by last)" in run_summary(by_last, "mgn")
    assert epoch_score({"epoch": 4, "train_mse": 1.0}, "last") < \
        epoch_score({"epoch": 3, "train_mse": 0.1}, "last")


def test_metrics_are_the_evaluations(runs, dataset):
    """val_rollout_* equal the rollout `thrombojax evaluate` measures on the same simulation."""
    trained = load_trained(runs[1], which="last")
    ds = open_dataset(dataset)
    names = trained.split.val
    radius = 0.37
    sims = prepare_val_rollouts(ds, names, trained.scaling, trained.step)
    got = val_rollout_metrics(trained.params, trained.stats, sims, radius)
    pos, nt = scaled_simulation(ds, names[0], trained.scaling)
    res = rollout_simulation(trained.step, trained.params, trained.stats, pos, nt, t0=1)
    model, cv = res.summary[trained.model.name]["mse@full"], \
        res.summary["constant velocity"]["mse@full"]
    assert got["val_rollout_mse"] == pytest.approx(model, rel=1e-5)
    assert got["val_rollout_mse_r2"] == pytest.approx(model / radius**2, rel=1e-5)
    assert got["val_rollout_cv_ratio"] == pytest.approx(model / cv, rel=1e-5)
    clot = nt == 1
    centroid = centroid_error(res.pred, res.true, clot)[-1]
    assert got["val_rollout_centroid_r"] == pytest.approx(centroid / radius, rel=1e-5)
    assert np.allclose(mse_per_step(res.pred, res.true, clot), res.curves[trained.model.name]
                       ["mse"])


def test_diverged_rollout_is_none_and_never_best(runs, dataset):
    trained = load_trained(runs[1], which="last")
    ds = open_dataset(dataset)
    sims = prepare_val_rollouts(ds, trained.split.val, trained.scaling, trained.step)
    nan_params = jax.tree.map(lambda x: x * np.nan, trained.params)
    got = val_rollout_metrics(nan_params, trained.stats, sims, 1.0)
    assert got == dict.fromkeys(VAL_ROLLOUT_KEYS)
    record = {"train_mse": 1.0, "val_mse": 0.5, **got}
    assert epoch_score(record, "rollout") == np.inf
    assert epoch_score(record, "mse") == 0.5
    assert epoch_score({"train_mse": 1.0, "val_mse": 0.5, "val_rollout_mse": 0.9},
                       "rollout") == 0.9
    assert best_epoch([{"epoch": 1, "train_loss": 1, "val_rollout_mse": None},
                       {"epoch": 2, "train_loss": 1, "val_rollout_mse": 3.0}])[0] == 2


def test_bad_values(dataset, tmp_path):
    with pytest.raises(ConfigError, match="select_by"):
        TrainConfig(select_by="rollouts")
    with pytest.raises(ConfigError, match="--n-val"):
        train(dataset, "mgn", tmp_path / "run", progress=False,
              **{**RUN, "n_val": 0, "select_by": "rollout"})
    with pytest.raises(SystemExit) as exit_:  # argparse: status 2, the choices named
        main(["train", "--dataset", str(dataset), "--model", "mgn", "--tiny", "--out",
              str(tmp_path / "cli"), "--select-by", "best", "--quiet"])
    assert exit_.value.code == 2
