"""The experiment runner: config files, --set, sharding, cost, CLI, resume, the report table."""

import json
import pathlib

import pytest

from thrombojax import study
from thrombojax.cli import main
from thrombojax.errors import ConfigError, OutputError
from thrombojax.experiments import execute
from thrombojax.experiments.data import ensure_dataset
from thrombojax.experiments.plan import (
    estimate,
    parse_worker,
    plan_runs,
    shard,
    train_windows,
)
from thrombojax.experiments.runner import run_experiment
from thrombojax.experiments.spec import (
    KINDS,
    SCALES,
    apply_sets,
    config_dir,
    find_experiment,
    list_experiments,
)
from thrombojax.models.registry import get_config
from thrombojax.train.config import TrainConfig

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

EXPECTED = {"rotation_sweep", "node_count_sweep", "bary_ratio_sweep", "test_mse", "rollouts",
            "rollout_timing", "generalisation", "stability_ladder", "hyperparameter_search"}


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("expdata")
    ensure_dataset("bendvessel-tiny", folder)
    return folder


def test_every_experiment_loads_at_every_scale():
    exps = {e.name: e for e in list_experiments()}
    assert set(exps) == EXPECTED
    assert {e.kind for e in exps.values()} == set(KINDS)
    for exp in exps.values():
        assert pathlib.Path(exp.path).stem == exp.name
        for scale in SCALES:
            sc = exp.scale(scale)
            assert isinstance(sc.train, TrainConfig)
            runs = plan_runs(exp, scale)
            assert runs and len({r.key for r in runs}) == len(runs)
            for run in runs:  # every run's model config builds (cpu: the small configs)
                get_config(run.model, tiny=run.train.tiny, **run.train.model_config)
    study_scale = exps["test_mse"].scale("study")
    assert study_scale.train.epochs == 300 and study_scale.seeds == (0, 1, 2, 3, 4)
    assert set(study_scale.models) == set(study.TEST_MSE["bendvessel"])
    ce = [r for r in plan_runs(exps["test_mse"], "study") if r.dataset == "clotentry"]
    assert ce and all(r.train.nodes_per_sample == 2048 for r in ce)


def test_set_overrides_a_scale_and_bad_keys_fail():
    exp = find_experiment("rotation_sweep")
    epochs = exp.scale("cpu").train.epochs
    assert epochs != 3
    edited = apply_sets(exp, "cpu", ["train.epochs=3", 'models=["mgn"]',
                                     "model_config.mgn.hidden=48", "seeds=2"])
    runs = plan_runs(edited, "cpu")
    assert {r.model for r in runs} == {"mgn"} and {r.seed for r in runs} == {0, 1}
    assert all(r.train.epochs == 3 and r.train.model_config["hidden"] == 48 for r in runs)
    assert plan_runs(exp, "cpu")[0].train.epochs == epochs  # the original is unchanged
    with pytest.raises(ConfigError, match="epochs"):
        apply_sets(exp, "cpu", ["train.epochs=0"])
    with pytest.raises(ConfigError, match="unknown training option"):
        apply_sets(exp, "cpu", ["train.epoch=3"])
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        apply_sets(exp, "cpu", ["train.epochs"])
    with pytest.raises(ConfigError, match="hiden"):
        apply_sets(exp, "cpu", ["model_config.mgn.hiden=3"])


def test_worker_shards_partition_the_run_list():
    runs = plan_runs(find_experiment("rotation_sweep"), "cpu")
    for n in (1, 2, 3, 7, len(runs) + 2):
        shards = [shard(runs, (i, n)) for i in range(n)]
        keys = [r.key for s in shards for r in s]
        assert sorted(keys) == sorted(r.key for r in runs) and len(keys) == len(set(keys))
        assert shards == [shard(plan_runs(find_experiment("rotation_sweep"), "cpu"), (i, n))
                          for i in range(n)]  # deterministic
    assert parse_worker("2/4") == (2, 4)
    for bad in ("4/4", "1", "a/b", "-1/2"):
        with pytest.raises(ConfigError, match="--worker"):
            parse_worker(bad)


def test_cost_estimate_counts_steps():
    exp = find_experiment("bary_ratio_sweep")
    est = estimate(exp, "cpu")
    runs = plan_runs(exp, "cpu")
    # 20 sims - 2 val - 1 test = 17 x 39 windows; bary ratio r adds r x as many samples
    sc = exp.scale("cpu")
    expect = sum(sc.train.epochs * -(-17 * 39 * (1 + r.train.bary_ratio) // 4) for r in runs)
    assert est["runs"] == len(runs) == len(sc.values) * len(sc.seeds) * len(sc.models)
    assert est["steps"] == expect
    assert est["seconds"] == pytest.approx(expect * exp.scale("cpu").step_s["mgn"])
    assert estimate(find_experiment("test_mse"), "study")["seconds"] is None  # not measured
    ladder = plan_runs(find_experiment("stability_ladder"), "cpu")
    # a split by name: 20 - 1 val - 3 test = 16 sims; push-forward and k-step windows are longer
    assert [train_windows(r) for r in ladder] == [16 * 39] * 2 + [16 * 38] + [16 * 36] * 2
    gen = plan_runs(find_experiment("generalisation"), "cpu")
    assert [train_windows(r, "generalisation") for r in gen[::3]] == [5 * 39, 10 * 39,
                                                                     15 * 39, 19 * 39]


def test_cli_list_and_bad_input(capsys, tmp_path):
    assert main(["experiment", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in EXPECTED) and "training steps" in out
    assert main(["experiment", "run", "nope", "--scale", "smoke", "--out",
                 str(tmp_path / "x")]) == 2
    assert "unknown experiment 'nope'" in capsys.readouterr().err
    assert main(["experiment", "run", "rotation_sweep", "--scale", "smoke", "--out",
                 str(tmp_path / "x"), "--set", "train.epochs=-1"]) == 2
    err = capsys.readouterr().err
    assert "rotation_sweep.toml" in err and "epochs" in err and "Traceback" not in err
    bad = tmp_path / "bad.toml"
    scale = '[{0}]\ndatasets = ["bendvessel-tiny"]\nmodels = ["mgn"]\nvalues = [0.0]\n'
    bad.write_text('name = "bad"\ntitle = "t"\nreproduces = "r"\nkind = "sweep"\n'
                   'sweep = "max_rotation"\n' + scale.format("smoke") + scale.format("cpu")
                   + scale.format("study") + '[study.train]\nepochs = "ten"\n')
    assert main(["experiment", "run", str(bad), "--scale", "smoke", "--out",
                 str(tmp_path / "y")]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "[study].train" in err and "epochs" in err
    assert config_dir().name == "configs"
    assert main(["experiment", "run", "rotation_sweep", "--scale", "study", "--out",
                 str(tmp_path / "z"), "--dry-run", "--worker", "1/4"]) == 0
    out = capsys.readouterr().out
    assert "9 of 36 runs" in out and "clotentry__mgn__max_rotation-0__s1" in out
    assert not (tmp_path / "z").exists()
    assert main(["experiment", "run", "test_mse", "--scale", "smoke", "--out",
                 str(tmp_path / "z"), "--trials", "3"]) == 2
    assert "--trials: only for a search" in capsys.readouterr().err


def test_experiment_resumes_without_redoing_finished_runs(data_dir, tmp_path, monkeypatch):
    exp = find_experiment("rotation_sweep")
    out = tmp_path / "rot"
    calls = []
    real_train = execute.train

    def counting_train(data, model, folder, **kw):
        calls.append((pathlib.Path(folder).name, bool(kw.get("resume"))))
        return real_train(data, model, folder, **kw)

    def killed_measure(kind, folder, *args):
        if folder.name.endswith("pi__s0"):
            raise KeyboardInterrupt  # killed after training the third run, before its result
        return real_measure(kind, folder, *args)

    real_measure = execute._measure
    monkeypatch.setattr(execute, "train", counting_train)
    monkeypatch.setattr(execute, "_measure", killed_measure)
    with pytest.raises(KeyboardInterrupt):
        run_experiment(exp, "smoke", out, data_dir=data_dir, log=lambda m: None)
    assert len(calls) == 3 and not (out / "table.md").exists()
    runs = sorted((out / "runs").iterdir())
    stamps = {p.name: (p / "result.json").stat().st_mtime_ns for p in runs
              if (p / "result.json").is_file()}
    assert len(stamps) == 2
    ckpt = {p.name: sorted(f.stat().st_mtime_ns for f in (p / "checkpoints").rglob("*")
                           if f.is_file()) for p in runs}

    monkeypatch.setattr(execute, "_measure", real_measure)
    calls.clear()
    res = run_experiment(exp, "smoke", out, data_dir=data_dir, log=lambda m: None)
    assert res["skipped"] == 2 and res["ran"] == 2 and res["finished"] == 4
    # the killed run resumed from its checkpoint; the last one trained afresh; no other run
    assert calls == [("bendvessel-tiny__mgn__max_rotation-pi__s0", True),
                     ("bendvessel-tiny__mgn__max_rotation-pi__s1", False)]
    for p in runs:
        if p.name in stamps:
            assert (p / "result.json").stat().st_mtime_ns == stamps[p.name]
        if p.name in ckpt:
            now = sorted(f.stat().st_mtime_ns for f in (p / "checkpoints").rglob("*")
                         if f.is_file())
            assert now == ckpt[p.name], p.name  # not retrained

    calls.clear()
    again = run_experiment(exp, "smoke", out, data_dir=data_dir, log=lambda m: None)
    assert again["ran"] == 0 and again["skipped"] == 4 and calls == []

    table = (out / "table.md").read_text()
    m, s = study.TEST_MSE["bendvessel"]["mgn"]
    assert f"{m:.4g} ± {s:.2g}" in table  # the study's number beside ours
    results = json.loads((out / "results.json").read_text())
    for group in results["groups"]:
        ours = [x["mse"] for x in group["metrics"]]
        assert len(ours) == 2
        mean = sum(ours) / 2
        assert f"{mean:.4g} ±" in table
    assert (out / "sweep.png").stat().st_size > 0
    assert "device" in table and "jax" in table
    if not any((p / "tensorboard").is_dir() for p in runs):
        pytest.importorskip("tensorboardX")
    for p in runs:
        assert list((p / "tensorboard").glob("events.out.tfevents.*")), p

    # other settings on a finished run are refused; another experiment's folder too
    edited = apply_sets(exp, "smoke", ["train.lr=0.01"])
    with pytest.raises(OutputError, match="other settings"):
        run_experiment(edited, "smoke", out, data_dir=data_dir, log=lambda m: None)
    with pytest.raises(OutputError, match="holds experiment 'rotation_sweep'"):
        run_experiment(find_experiment("bary_ratio_sweep"), "smoke", out, data_dir=data_dir)
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep")
    with pytest.raises(OutputError, match="holds no thrombojax experiment"):
        run_experiment(exp, "smoke", foreign, data_dir=data_dir)
    assert (foreign / "notes.txt").read_text() == "keep"


def test_tensorboard_events_follow_metrics_and_are_optional(tmp_path, monkeypatch):
    import sys

    from thrombojax.experiments.tensorboard import tensorboard_logger

    log = tmp_path / "metrics.jsonl"
    log.write_text("")
    monkeypatch.setitem(sys.modules, "tensorboardX", None)  # not installed
    callback, close = tensorboard_logger(tmp_path)
    assert callback is None and not (tmp_path / "tensorboard").exists()
    close()
    monkeypatch.delitem(sys.modules, "tensorboardX")
    pytest.importorskip("tensorboardX")
    callback, close = tensorboard_logger(tmp_path)
    callback(1, {"loss": 0.5, "mse": 0.25})
    log.write_text(json.dumps({"epoch": 1, "step": 2, "train_loss": 0.4, "val_mse": 0.125})
                   + "\n")
    callback(2, {"loss": 0.3, "mse": 0.2})
    close()
    scalars = _read_events(tmp_path / "tensorboard")
    assert [(s, pytest.approx(v)) for t, s, v in scalars if t == "step/loss"] == [(1, 0.5),
                                                                                  (2, 0.3)]
    assert [(s, v) for t, s, v in scalars if t == "epoch/val_mse"] == [(2, 0.125)]


def _read_events(folder):
    """(tag, step, value) of every scalar in the event files (TFRecord: length, crc, data, crc)."""
    import struct

    from tensorboardX.proto import event_pb2

    out = []
    for path in sorted(folder.glob("events.out.tfevents.*")):
        raw = path.read_bytes()
        i = 0
        while i < len(raw):
            (n,) = struct.unpack("<Q", raw[i:i + 8])
            event = event_pb2.Event.FromString(raw[i + 12:i + 12 + n])
            i += 12 + n + 4
            out += [(v.tag, event.step, v.simple_value) for v in event.summary.value]
    return out


def test_search_without_optuna_is_one_clear_error(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "optuna", None)
    assert main(["experiment", "run", "hyperparameter_search", "--scale", "smoke", "--out",
                 str(tmp_path / "s")]) == 2
    assert "needs Optuna" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_seeds_option_is_a_count_or_a_list():
    from thrombojax.cli.experiment_commands import _seeds

    assert _seeds("3") == (0, 1, 2) and _seeds("0,") == (0,) and _seeds("2,5") == (2, 5)
    assert _seeds(None) is None
    with pytest.raises(ConfigError, match="give a list: --seeds 0,"):
        _seeds("0")
    with pytest.raises(ConfigError, match=">= 0"):
        _seeds("-1,2")
