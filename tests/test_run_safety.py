"""Nothing silent: a run meets only the data it was made for, corrupt run folders and bad options
are one-line errors (exit 2), and a run's config.json reloads."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pathlib
import shutil

import numpy as np
import pytest
from dataset_factory import accelerating_sims

from thrombojax.cli import main
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset
from thrombojax.train.config import TrainConfig, load_config_file
from thrombojax.train.guards import NonFiniteError, check_finite, check_in_box


def tiny_sims(scale: float = 10.0, shift: float = 0.0, prefix: str = "sim") -> list[Simulation]:
    return accelerating_sims(scale=scale, shift=shift, prefix=prefix)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from thrombojax.train.loop import train

    root = tmp_path_factory.mktemp("runsafety")
    data = write_dataset(root / "tiny.h5", tiny_sims(), name="tiny", source="test")
    run = root / "run"
    train(data, "mgn", run, epochs=1, tiny=True, n_val=1, batch_size=2, warmup_epochs=0,
          progress=False)
    return data, run, root


def one_line_error(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, lines
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def evaluate(run, data, out) -> int:
    return main(["evaluate", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--quiet"])


BAD_OPTIONS = [
    (["train", "--max-rotation", "nan"], "--max-rotation"),
    (["train", "--warmup-epochs", "-1"], "--warmup-epochs"),
    (["train", "--noise-std", "-0.1"], "--noise-std"),
    (["train", "--skip-frames", "-2"], "--skip-frames"),
    (["train", "--lr", "inf"], "--lr"),
    (["train", "--epochs", "0"], "--epochs"),
    (["train", "--bary-ratio", "1e13"], "--bary-ratio"),  # memory: no machine has 960 TB
    (["train", "--n-test", "-1"], "--n-test"),
]


@pytest.mark.parametrize("argv,needle", BAD_OPTIONS)
def test_bad_train_options_are_named_before_any_work(argv, needle, tmp_path, capsys):
    base = ["--dataset", str(tmp_path / "none.h5"), "--model", "mgn", "--out",
            str(tmp_path / "r")]
    try:
        code = main([argv[0], *base, *argv[1:]])
    except SystemExit as exc:  # argparse
        code = exc.code
    assert code == 2
    one_line_error(capsys, needle)
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("argv,needle", [
    (["generate", "bendvessel-tiny", "--out", "x.h5", "--seed", "-1"], "--seed"),
    (["generate", "bendvessel-tiny", "--out", "x.h5", "--sims", "0"], "--sims"),
    (["evaluate", "--run", "r", "--dataset", "d.h5", "--skip", "-1"], "--skip"),
    (["rollout", "--run", "r", "--dataset", "d.h5", "--out", "o", "--steps", "0"], "--steps"),
    (["bench", "--repeats", "0"], "--repeats"),
    (["import", "vtu", "src", "--out", "x.h5", "--dt", "-1"], "--dt"),
])
def test_bad_options_of_other_commands(argv, needle, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    one_line_error(capsys, needle)


@pytest.mark.parametrize("payload,needle", [
    ({"epochs": "ten"}, "epochs"), ({"max_rotation": [1, 2]}, "max_rotation"),
    ({"warmup_epochs": -3}, "warmup"), ({"checkpoint_every": -1}, "checkpoint_every"),
    ({"tiny": "yes"}, "tiny"), ({"lr": None, "n_val": 1.5}, "n_val"),
])
def test_wrongly_typed_config_json(payload, needle, tmp_path):
    path = tmp_path / "c.json"
    path.write_text(json.dumps(payload))
    with pytest.raises(ConfigError, match=needle):
        load_config_file(path)


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.startswith("thrombojax ")


def test_run_config_reloads_as_a_training_config(tiny_run):
    _, run, _ = tiny_run
    saved = json.loads((run / "config.json").read_text())
    cfg = load_config_file(run / "config.json")
    assert cfg.train == TrainConfig.from_dict(saved["train"])
    assert cfg.train.epochs == 1 and cfg.train.tiny and cfg.train.n_val == 1


def test_evaluate_refuses_to_replace_its_outputs(tiny_run, capsys):
    data, run, root = tiny_run
    assert evaluate(run, data, root / "ev") == 0
    before = (root / "ev" / "evaluate.json").read_text()
    capsys.readouterr()
    assert evaluate(run, data, root / "ev") == 2
    one_line_error(capsys, "evaluate.json", "--force")
    assert (root / "ev" / "evaluate.json").read_text() == before
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(root / "ev"), "--quiet", "--force"]) == 0


def test_train_refuses_existing_run_and_other_dataset_on_resume(tiny_run, capsys):
    data, run, root = tiny_run
    argv = ["train", "--dataset", str(data), "--model", "mgn", "--out", str(run), "--tiny",
            "--epochs", "1", "--quiet"]
    assert main(argv) == 2
    one_line_error(capsys, str(run), "--resume")
    other = write_dataset(root / "other.h5", tiny_sims(scale=11.0), name="o", source="test")
    ckpt = sorted((run / "checkpoints" / "last").iterdir())
    assert main(["train", "--dataset", str(other), "--model", "mgn", "--out", str(run),
                 "--resume", "--quiet"]) == 2
    one_line_error(capsys, "--resume", "differs")
    assert sorted((run / "checkpoints" / "last").iterdir()) == ckpt  # nothing trained


def test_data_far_outside_the_runs_box_is_refused(tiny_run, capsys):
    data, run, root = tiny_run
    far = write_dataset(root / "x1000.h5", tiny_sims(scale=10_000.0), name="far", source="t")
    assert evaluate(run, far, root / "ev_far") == 2
    one_line_error(capsys, "x1000.h5", "sim_", "scaled")
    assert not (root / "ev_far" / "evaluate.json").exists()
    with pytest.warns(UserWarning, match="outside the training box"):
        check_in_box(np.full((2, 3, 3), 1.5), "s", "d.h5", "run")


def test_dataset_without_the_runs_test_simulation(tiny_run, capsys):
    """Another dataset: all of its simulations by default (said so); the run's split asked for
    explicitly is a one-line error naming the file and the missing simulations."""
    _, run, root = tiny_run
    renamed = write_dataset(root / "renamed.h5", tiny_sims(prefix="other"), name="r",
                            source="t")
    assert evaluate(run, renamed, root / "ev_renamed") == 0
    assert "not the run's training dataset" in capsys.readouterr().out
    res = json.loads((root / "ev_renamed" / "evaluate.json").read_text())
    assert sorted(res["simulations"]) == sorted(open_dataset(renamed).names)
    assert main(["evaluate", "--run", str(run), "--dataset", str(renamed), "--out",
                 str(root / "ev_renamed2"), "--split", "test", "--quiet"]) == 2
    one_line_error(capsys, "renamed.h5", "sim_")


def _copy_run(run, root, name):
    dst = root / name
    shutil.rmtree(dst, ignore_errors=True)
    shutil.copytree(run, dst)
    return dst


def _edit_config(run, **changes):
    cfg = json.loads((run / "config.json").read_text())
    for key, value in changes.items():
        section, _, field = key.partition("__")
        if field:
            cfg[section][field] = value
        else:
            cfg[section] = value
    (run / "config.json").write_text(json.dumps(cfg))


def test_empty_test_split_is_named_for_evaluate_and_rollout(tiny_run, capsys):
    data, run, root = tiny_run
    bad = _copy_run(run, root, "no_test")
    _edit_config(bad, split__test=[])
    assert evaluate(bad, data, root / "ev_nt") == 2
    one_line_error(capsys, "'test' split is empty")
    assert main(["rollout", "--run", str(bad), "--dataset", str(data), "--out",
                 str(root / "ro_nt"), "--quiet"]) == 2
    one_line_error(capsys, "'test' split is empty")


def _flip_params(run):
    flipped = 0
    for path in (run / "checkpoints" / "best").rglob("*"):
        if path.is_file() and "params" in path.parts and path.parent.name == "d":
            raw = bytearray(path.read_bytes())
            raw[len(raw) // 2] ^= 0xFF
            path.write_bytes(bytes(raw))
            flipped += 1
    assert flipped


def _truncate_config(run):
    text = (run / "config.json").read_text()
    (run / "config.json").write_text(text[: len(text) // 2])


def _delete_params(run):
    for path in (run / "checkpoints" / "best").glob("*/params"):
        shutil.rmtree(path)


def _wrong_model(run):
    cfg = json.loads((run / "config.json").read_text())
    cfg["train"]["model_config"]["hidden"] *= 2
    (run / "config.json").write_text(json.dumps(cfg))


def _foreign_model(run):
    _edit_config(run, model="transolver")


def _empty_meta(run):
    (run / "config.json").write_text("{}")


@pytest.mark.parametrize("corrupt,needle", [
    (_truncate_config, "config.json"), (_empty_meta, "config.json"),
    (_delete_params, "checkpoint"), (_flip_params, "checkpoint"),
    (_wrong_model, "config.json"), (_foreign_model, "mgn"),
])
def test_corrupt_run_folders_are_one_line_errors(tiny_run, capsys, corrupt, needle):
    data, run, root = tiny_run
    bad = _copy_run(run, root, f"bad_{corrupt.__name__}")
    corrupt(bad)
    assert evaluate(bad, data, root / f"ev_{corrupt.__name__}") == 2
    one_line_error(capsys, str(bad.name), needle)


def test_non_finite_metrics_are_errors():
    check_finite({"val_mse": 0.1, "epoch": 3}, "run")
    with pytest.raises(NonFiniteError, match="val_mse is nan"):
        check_finite({"train_mse": 0.1, "val_mse": math.nan}, "run: epoch 2")


def test_rollout_dotted_names_do_not_overwrite_each_other(tiny_run):
    _, run, root = tiny_run
    sims = [dataclasses.replace(s, name=f"flow_{i}.5")
            for i, s in enumerate(tiny_sims(prefix="flow"))]
    dotted = write_dataset(root / "dotted.h5", sims, name="d", source="t")
    out = root / "ro_dotted"
    assert main(["rollout", "--run", str(run), "--dataset", str(dotted), "--out", str(out),
                 "--sim", "flow_1.5", "--sim", "flow_2.5", "--skip", "5", "--steps", "2",
                 "--no-gif", "--quiet"]) == 0
    names = sorted(p.name for p in out.glob("*.xdmf"))
    assert names == ["flow_1.5_prediction.xdmf", "flow_1.5_truth.xdmf",
                     "flow_2.5_prediction.xdmf", "flow_2.5_truth.xdmf"]
    assert len(open_dataset(out / "flow_1.5_rollout.h5").names) == 1


@pytest.mark.parametrize("preset", ["bendvessel-tiny", "clotentry-tiny"])
def test_tiny_presets_fit_the_default_split(preset):
    from thrombojax.data.splits import split_simulations
    from thrombojax.sim.presets import get_preset

    cfg = TrainConfig()
    names = [f"{preset}_{i:03d}" for i in range(get_preset(preset).n_sims)]
    split = split_simulations(names, n_test=cfg.n_test, n_val=cfg.n_val, seed=cfg.split_seed)
    assert split.train and len(split.val) == cfg.n_val and len(split.test) == cfg.n_test


def test_train_summary_names_best_metric_epochs_and_files(tiny_run):
    from thrombojax.train.summary import run_summary

    _, run, _ = tiny_run
    text = run_summary(run, "mgn")
    best = min(json.loads(ln)["val_mse"] for ln in (run / "metrics.jsonl").read_text().splitlines()
               if "val_mse" in ln)
    assert "1 epoch(s)" in text and f"{best:.4g}" in text and "validation" in text
    assert str(run / "config.json") in text and "checkpoints" in text


def test_warnings_for_whole_run_warmup_and_large_cpu_benchmarks():
    import jax

    from thrombojax.eval.bench import STUDY_CASES
    from thrombojax.train.guards import warn_large_cpu_cases, warn_schedule

    with pytest.warns(UserWarning, match="never reaches its peak"):
        warn_schedule(5, 10.0)
    if jax.default_backend() == "cpu":
        with pytest.warns(UserWarning, match="27,000 nodes"):
            warn_large_cpu_cases(("bendvessel", "clotentry-full"), None, STUDY_CASES)


def test_bench_says_where_it_wrote_and_refuses_to_replace(tmp_path, capsys):
    argv = ["bench", "--models", "mgn", "--cases", "bendvessel", "--tiny", "--nodes", "64",
            "--max-steps", "2", "--repeats", "1", "--out", str(tmp_path / "b"), "--quiet"]
    assert main(argv) == 0
    assert f"wrote {tmp_path / 'b' / 'bench.json'}" in capsys.readouterr().out
    before = (tmp_path / "b" / "bench.json").read_text()
    assert main(argv) == 2
    one_line_error(capsys, "bench.json", "--force")
    assert (tmp_path / "b" / "bench.json").read_text() == before


def test_force_deletes_old_checkpoints_out_of_the_loaders_path(tmp_path, monkeypatch):
    """`train --force` renames the old checkpoints away before deleting them: a process killed
    mid-deletion (here: rmtree interrupted after one file) leaves no half checkpoint at
    checkpoints/, only a temporary the next run removes (the kill -9 trials found a
    half-deleted best/1 before this)."""
    import subprocess
    import sys

    from thrombojax.train import guards

    run = tmp_path / "run"
    (run / "checkpoints" / "best" / "1" / "params").mkdir(parents=True)
    for name in ("_METADATA", "d0", "d1"):
        (run / "checkpoints" / "best" / "1" / "params" / name).write_text("x")
    (run / "notes.txt").write_text("mine")

    def killed_rmtree(path, ignore_errors=False):
        next(pathlib.Path(path).rglob("_METADATA")).unlink()  # deleted one file, then "killed"
        raise KeyboardInterrupt

    monkeypatch.setattr(shutil, "rmtree", killed_rmtree)
    with pytest.raises(KeyboardInterrupt):
        guards.clear_run(run)
    assert not (run / "checkpoints").exists()  # nothing half-deleted where loaders look
    left = [p for p in run.iterdir() if p.name != "notes.txt"]
    assert len(left) == 1 and ".tjxtmp-" in left[0].name
    monkeypatch.undo()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = left[0].rename(run / left[0].name.replace(f"-{os.getpid()}-", f"-{dead}-"))
    guards.clear_run(run)  # the next run: the dead process's temporary goes
    assert not stale.exists() and sorted(p.name for p in run.iterdir()) == ["notes.txt"]
