"""The training loop end to end: run directory, CLI, load_trained, NaN guard, exact resume."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import jax
import numpy as np
import pytest

from thrombojax.cli import main
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import Simulation, write_dataset
from thrombojax.train.config import TrainConfig, parse_angle
from thrombojax.train.loop import TrainingDivergedError, train
from thrombojax.train.state import load_trained, restore_checkpoint
from thrombojax.types import NodeType

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

# 3 train simulations x 4 windows, batch 4, bary_ratio 1 -> 6 steps per epoch
SMALL = dict(tiny=True, batch_size=4, lr=3e-3, warmup_epochs=0.5, n_val=1, n_test=1,
             nodes_per_sample=40, bary_ratio=1.0, bary_radius=0.5, max_rotation=np.pi)


def _simulation(i: int, n_frames: int = 6) -> Simulation:
    rng = np.random.default_rng(i)
    ang = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    vessel = np.stack([3 * np.cos(ang), 3 * np.sin(ang), rng.uniform(-1, 1, 40)], 1)
    clot = rng.normal(0, 0.8, (16, 3))
    t = np.arange(n_frames)[:, None, None]
    moving = clot[None] * (1 + 0.02 * t) + (0.1 + 0.01 * i) * t**1.5 * np.array([1.0, 0.3, 0.0])
    pos = np.concatenate([np.broadcast_to(vessel, (n_frames, 40, 3)), moving], axis=1)
    node_type = np.array([NodeType.VESSEL] * 40 + [NodeType.CLOT] * 16, np.int8)
    return Simulation(name=f"sim{i}", positions=pos.astype(np.float32), node_type=node_type,
                      attrs={"dt": 0.1})


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    path = tmp_path_factory.mktemp("data") / "synthetic.h5"
    return write_dataset(path, [_simulation(i) for i in range(5)], name="synthetic", source="test")


def _params(run_dir, which="last"):
    params, _, meta = restore_checkpoint(run_dir / "checkpoints" / which)
    return params, meta


def test_parse_angle():
    assert parse_angle("pi") == pytest.approx(np.pi)
    assert parse_angle("pi/2") == pytest.approx(np.pi / 2)
    assert parse_angle("0.5pi") == pytest.approx(np.pi / 2)
    assert parse_angle("90deg") == pytest.approx(np.pi / 2)
    assert parse_angle("1.5") == 1.5
    with pytest.raises(ConfigError):
        parse_angle("half a turn")
    with pytest.raises(ConfigError):
        TrainConfig.from_dict({"epochs": 3, "lr_typo": 1.0})


def test_cli_train_writes_a_run_and_loads(dataset, tmp_path):
    out = tmp_path / "run"
    cfg = tmp_path / "cfg.json"
    cfg.write_text(json.dumps({k: v for k, v in SMALL.items() if k != "max_rotation"}))
    code = main(["train", "--dataset", str(dataset), "--model", "mgn", "--config", str(cfg),
                 "--out", str(out), "--epochs", "2", "--max-rotation", "pi/2", "--quiet"])
    assert code == 0
    for name in ("config.json", "metrics.jsonl", "loss.png"):
        assert (out / name).is_file()
    records = [json.loads(ln) for ln in (out / "metrics.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in records] == [1, 2] and records[-1]["step"] == 12
    assert all(np.isfinite(r["val_mse"]) and r["val_mse"] > 0 for r in records)
    config = json.loads((out / "config.json").read_text())
    assert config["train"]["max_rotation"] == pytest.approx(np.pi / 2)
    assert config["steps_per_epoch"] == 6 and config["budget"] == 64
    assert len(config["split"]["val"]) == 1 and len(config["split"]["train"]) == 3
    trained = load_trained(out)
    assert trained.model.name == "mgn" and trained.config["model"] == "mgn"
    np.testing.assert_allclose(trained.stats.std, config["stats"]["std"])
    best_step = min(records, key=lambda r: r["val_mse"])["step"]
    assert _params(out, "best")[1]["epoch"] == best_step // 6
    last = load_trained(out, which="last")
    same = jax.tree.map(np.array_equal, jax.tree.map(np.asarray, last.params),
                        jax.tree.map(np.asarray, _params(out)[0]))
    assert all(jax.tree.leaves(same))
    # a second run into the same directory without --resume is refused (exit status 2)
    assert main(["train", "--dataset", str(dataset), "--model", "mgn", "--out", str(out),
                 "--quiet", "--tiny"]) == 2


def test_nan_guard_keeps_last_good_checkpoint(dataset, tmp_path):
    out = tmp_path / "nan"
    with pytest.raises(TrainingDivergedError, match="last good checkpoint"):
        train(dataset, "mgn", out, progress=False, epochs=3, **{**SMALL, "lr": 1e30,
                                                               "warmup_epochs": 0.0})
    records = [json.loads(ln) for ln in (out / "metrics.jsonl").read_text().splitlines()]
    assert records[-1]["event"] == "nan"
    params, _ = _params(out) if (out / "checkpoints" / "last").exists() else (None, None)
    if params is not None:  # any checkpoint that was written holds finite parameters
        assert all(np.all(np.isfinite(x)) for x in jax.tree.leaves(params))


CHILD = textwrap.dedent(
    """
    import sys, time
    from thrombojax.train.loop import train
    kill_at = int(sys.argv[3])

    def callback(step, metrics):
        if step == kill_at:
            print("READY", flush=True)
            time.sleep(600)

    train(sys.argv[1], "mgn", sys.argv[2], progress=False, callback=callback, **{kwargs})
    """
)


def test_resume_after_sigkill_is_exact(dataset, tmp_path):
    kwargs = dict(SMALL, epochs=2, checkpoint_every=1)
    straight = tmp_path / "straight"
    train(dataset, "mgn", straight, progress=False, **kwargs)

    resumed = tmp_path / "resumed"
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD.replace("{kwargs}", repr(kwargs)), str(dataset),
         str(resumed), "5"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ),
    )
    deadline = time.time() + 240
    line = ""
    while time.time() < deadline and "READY" not in line:
        line = child.stdout.readline()
        if not line and child.poll() is not None:
            break
    assert "READY" in line, child.stderr.read()[-3000:]
    child.send_signal(signal.SIGKILL)  # killed mid-epoch (step 5 of 6), no chance to clean up
    child.wait(timeout=30)
    _, meta = _params(resumed)
    assert (meta["epoch"], meta["position"]) == (0, 5)

    train(dataset, "mgn", resumed, progress=False, resume=True)
    a, meta_a = _params(straight)
    b, meta_b = _params(resumed)
    assert meta_a["epoch"] == meta_b["epoch"] == 2
    equal = jax.tree.map(np.array_equal, a, b)
    assert all(jax.tree.leaves(equal)), "resumed parameters differ from the straight run"
    log_a = (straight / "metrics.jsonl").read_text().splitlines()
    log_b = (resumed / "metrics.jsonl").read_text().splitlines()
    strip = [{k: v for k, v in json.loads(ln).items() if k != "time_s"} for ln in log_a]
    assert strip == [{k: v for k, v in json.loads(ln).items() if k != "time_s"} for ln in log_b]
    with pytest.raises(ConfigError):
        train(dataset, "mgn", resumed, progress=False, resume=True, epochs=7)


def test_run_config_reloads_and_repeats_the_run(dataset, tmp_path):
    """config.json loads back into the same dataclasses; --config RUN/config.json repeats RUN."""
    from thrombojax.train.config import RunConfig, load_config_file

    first = tmp_path / "first"
    train(dataset, "mgn", first, progress=False, epochs=1, rollout_steps=2,
          model_config={"hidden": 12}, **SMALL)
    run = load_config_file(first / "config.json")
    assert isinstance(run, RunConfig) and run.model == "mgn"
    assert run.train.rollout_steps == 2 and run.train.model_config["hidden"] == 12
    assert run.train.batch_size == 4 and run.train.lr == 3e-3
    assert RunConfig.from_dict(run.to_dict()) == run
    assert load_trained(first).run == run
    again = tmp_path / "again"
    assert main(["train", "--config", str(first / "config.json"), "--out", str(again),
                 "--quiet"]) == 0
    a, b = ((json.loads(ln) for ln in (d / "metrics.jsonl").read_text().splitlines())
            for d in (first, again))
    ra, rb = next(a), next(b)
    assert ra["train_loss"] == rb["train_loss"] and ra["val_mse"] == rb["val_mse"]
    assert load_config_file(again / "config.json") == run


def test_split_by_name(dataset, tmp_path):
    """Named simulations become the test / validation parts; the rest trains."""
    cfg = TrainConfig(test_sims=["sim4"], val_sims=("sim0",))
    assert cfg.test_sims == ("sim4",) and TrainConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ConfigError, match="test_sims"):
        TrainConfig(test_sims="sim4")
    trained = train(dataset, "mgn", tmp_path / "named", progress=False, epochs=1,
                    **{**SMALL, "test_sims": ["sim4"], "val_sims": ["sim0"]})
    assert trained.split.test == ("sim4",) and trained.split.val == ("sim0",)
    assert trained.split.train == ("sim1", "sim2", "sim3")
    with pytest.raises(ConfigError, match="unknown simulation"):
        train(dataset, "mgn", tmp_path / "bad", progress=False, epochs=1,
              **{**SMALL, "test_sims": ["nope"]})
