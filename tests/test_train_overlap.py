"""The training loop reads metrics one step behind (host/device overlap, issue 17).

Runs with the overlap give exactly the runs of reading every step at once
(``thrombojax.train.loop._OVERLAP = False``): the same per-step metrics in the same order, the
same ``metrics.jsonl`` and the same final parameters; a divergence stops at the same step with
the same log and no checkpoint of non-finite parameters.
"""

import json

import jax
import numpy as np
import pytest
from test_train_loop import SMALL, _simulation

from thrombojax.io.hdf5 import write_dataset
from thrombojax.train import loop
from thrombojax.train.loop import TrainingDivergedError, train
from thrombojax.train.state import restore_checkpoint


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "synthetic.h5"
    return write_dataset(path, [_simulation(i) for i in range(5)], name="synthetic", source="test")


def _run(dataset, out, overlap, monkeypatch, **kwargs):
    """Train with or without the overlap; returns the callback's (step, metrics) in order."""
    monkeypatch.setattr(loop, "_OVERLAP", overlap)
    seen = []
    try:
        train(dataset, "mgn", out, progress=False, callback=lambda s, m: seen.append((s, m)),
              **kwargs)
    finally:
        monkeypatch.undo()
    return seen


def _log(out):
    lines = (out / "metrics.jsonl").read_text().splitlines()
    return [{k: v for k, v in json.loads(ln).items() if k != "time_s"} for ln in lines]


def _params(out, which):
    return jax.tree.map(np.asarray, restore_checkpoint(out / "checkpoints" / which)[0])


# checkpoint_every 4 with 6 steps per epoch: read-at-once steps mid-epoch (4, 8) and at epoch
# ends (6, 12), deferred ones between them
@pytest.mark.parametrize("checkpoint_every", [0, 4])
def test_overlap_gives_the_same_run(dataset, tmp_path, monkeypatch, checkpoint_every):
    kwargs = dict(SMALL, epochs=2, checkpoint_every=checkpoint_every)
    behind = _run(dataset, tmp_path / "behind", True, monkeypatch, **kwargs)
    at_once = _run(dataset, tmp_path / "at_once", False, monkeypatch, **kwargs)
    assert [s for s, _ in behind] == list(range(1, 13))
    assert behind == at_once  # every step's loss, mse and node count, in order
    assert len({m["loss"] for _, m in behind}) > 1
    assert _log(tmp_path / "behind") == _log(tmp_path / "at_once")
    for which in ("last", "best"):
        a, b = _params(tmp_path / "behind", which), _params(tmp_path / "at_once", which)
        assert all(jax.tree.leaves(jax.tree.map(np.array_equal, a, b)))


def test_overlap_stops_on_the_same_non_finite_step(dataset, tmp_path, monkeypatch):
    kwargs = {**SMALL, "epochs": 2, "lr": 1e30, "warmup_epochs": 0.0}
    logs = []
    for overlap in (True, False):
        out = tmp_path / str(overlap)
        with pytest.raises(TrainingDivergedError, match="last good checkpoint"):
            _run(dataset, out, overlap, monkeypatch, **kwargs)
        logs.append(_log(out))
        assert not (out / "checkpoints" / "last").exists()  # diverged within the first epoch
    assert logs[0] == logs[1] and logs[0][-1]["event"] == "nan"
    assert logs[0][-1]["step"] < 6  # a deferred (mid-epoch) step
