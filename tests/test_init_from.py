"""Fine-tuning: ``thrombojax train --init-from RUN`` starts from another run's weights (same model
and step inputs) with a fresh optimiser, e.g. to train with an unrolled loss after single-step
training (:func:`thrombojax.train.state.warm_start`)."""

import jax
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.train.config import TrainConfig


def _leaves(params):
    return [np.asarray(x) for x in jax.tree.leaves(params)]


def _max_diff(a, b):
    return max(float(np.abs(x - y).max()) for x, y in zip(_leaves(a), _leaves(b), strict=True))


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A tiny trained run to start from (:func:`dataset_factory.train_tiny_cli`): ``(dataset,
    run)``; the tests below only read it."""
    from dataset_factory import train_tiny_cli

    return train_tiny_cli(tmp_path_factory.mktemp("source"), n_nodes=60)


def test_a_run_started_from_another_run_starts_from_its_weights(tmp_path, source):
    from thrombojax.cli import main
    from thrombojax.train.state import load_trained

    data, run = source
    start = load_trained(run, which="last")
    common = ["train", "--dataset", str(data), "--model", "mgn", "--tiny", "--epochs", "1",
              "--batch-size", "2", "--n-val", "1", "--n-test", "1", "--warmup-epochs", "0.5",
              "--lr", "1e-9", "--quiet"]
    tuned, fresh = tmp_path / "tuned", tmp_path / "fresh"
    assert main([*common, "--out", str(tuned), "--init-from", str(run),
                 "--init-checkpoint", "last", "--rollout-steps", "2"]) == 0
    assert main([*common, "--out", str(fresh), "--rollout-steps", "2"]) == 0
    after = load_trained(tuned, which="last")
    # a learning rate of 1e-9 leaves the weights where they started: the source run's
    assert _max_diff(after.params, start.params) < 1e-6
    assert after.run.train.init_from == str(run) and after.run.train.init_which == "last"
    assert after.run.train.rollout_steps == 2
    # the same training without --init-from starts from its own random weights
    assert _max_diff(load_trained(fresh, which="last").params, start.params) > 1e-3


def test_weights_that_do_not_fit_are_refused_naming_the_run(tmp_path, capsys, source):
    from thrombojax.cli import main

    data, run = source
    common = ["train", "--dataset", str(data), "--tiny", "--epochs", "1", "--batch-size", "2",
              "--n-val", "1", "--n-test", "1", "--warmup-epochs", "0.5", "--quiet",
              "--init-from", str(run)]
    capsys.readouterr()
    assert main([*common, "--model", "mgn", "--out", str(tmp_path / "a"), "--history", "3"]) == 2
    err = capsys.readouterr().err
    assert f"--init-from {run}: its 'best' weights do not fit" in err
    assert "node_encoder" in err and "there" in err
    assert main([*common[:-1], str(tmp_path / "nowhere"), "--model", "mgn", "--out",
                 str(tmp_path / "c")]) == 2
    assert f"--init-from {tmp_path / 'nowhere'}: " in capsys.readouterr().err
    # the run it starts from is an input: never written over, not even with --force
    assert main([*common, "--model", "mgn", "--out", str(run), "--force"]) == 2
    assert "--init-from names the run this training would write over" in capsys.readouterr().err
    assert (run / "checkpoints" / "best").is_dir() and (run / "config.json").is_file()
    assert main([*common, "--model", "transolver", "--out", str(tmp_path / "b")]) == 2
    assert f"--init-from {run}: a 'mgn' run; this training is of 'transolver'" in (
        capsys.readouterr().err)


def test_init_options_are_checked():
    with pytest.raises(ConfigError, match="init_which"):
        TrainConfig(init_which="first")
    with pytest.raises(ConfigError, match="init_from"):
        TrainConfig(init_from=3)
    assert TrainConfig().init_from == "" and TrainConfig().init_which == "best"
