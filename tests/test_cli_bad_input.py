"""Every subcommand that reads a dataset, on every malformed dataset: exit 2 and one line naming
the file (and the simulation and field where there is one), never a traceback, nothing written.
One validation for every reader: `train`, `evaluate`, `rollout`, `bench` and `export` reject
exactly what `info` rejects."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from dataset_factory import BAD_FILES, _edit, _replace, write_good

from thrombojax.cli import main


def _attrs(**values):
    def fn(g: h5py.Group) -> None:
        for key, value in values.items():
            g.attrs[key] = value
    return fn


def _huge_positions(g: h5py.Group) -> None:
    del g["positions"]
    g.create_dataset("positions", shape=(500, 1_000_000, 3), dtype="f4")  # 6 GB, none stored


EXTRA = {
    "cells_index_a_million": (lambda p: _edit(p, lambda g: _replace(
        g, "clot_cells", np.array([[0, 1, 2, 1_000_000]], np.int32))), "sim_0", "clot_cells"),
    "negative_dt": (lambda p: _edit(p, _attrs(dt=-1.0)), "sim_0", "dt"),
    "text_dt": (lambda p: _edit(p, _attrs(dt="fast")), "sim_0", "dt"),
    "array_dt": (lambda p: _edit(p, _attrs(dt=np.ones(3))), "sim_0", "dt"),
    "corrupt_json_attr": (lambda p: _edit(p, _attrs(_json_attrs='["extra"]', extra="{oops")),
                          "sim_0", "attrs"),
    "huge_declared_positions": (lambda p: _edit(p, _huge_positions), "sim_0", "positions"),
}
CORPUS = {**BAD_FILES, **EXTRA}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    return {name: build(root / f"{name}.h5") for name, (build, _, _) in CORPUS.items()}


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    from thrombojax.train.loop import train

    root = tmp_path_factory.mktemp("goodrun")
    data = write_good(root / "good.h5", n_sims=3)
    train(data, "mgn", root / "run", epochs=1, tiny=True, n_val=1, n_test=1, batch_size=1,
          warmup_epochs=0, progress=False)
    return root / "run"


def _commands(path: Path, run: Path, out: Path) -> dict[str, list[str]]:
    return {
        "info": ["info", str(path)],
        "export": ["export", str(path), "--out", str(out / "ex"), "--quiet"],
        "train": ["train", "--dataset", str(path), "--model", "mgn", "--out", str(out / "run"),
                  "--tiny", "--epochs", "1", "--n-val", "0", "--quiet"],
        "evaluate": ["evaluate", "--run", str(run), "--dataset", str(path), "--split", "all",
                     "--out", str(out / "ev"), "--quiet"],
        "rollout": ["rollout", "--run", str(run), "--dataset", str(path), "--split", "all",
                    "--out", str(out / "ro"), "--steps", "1", "--no-gif", "--quiet"],
        "bench": ["bench", "--models", "mgn", "--cases", "bendvessel", "--tiny", "--nodes", "8",
                  "--max-steps", "1", "--repeats", "1", "--dataset", str(path), "--quiet"],
    }


@pytest.mark.parametrize("command", ["info", "export", "train", "evaluate", "rollout", "bench"])
def test_every_reader_rejects_every_bad_file(command, corpus, good_run, tmp_path, capsys):
    failures = []
    for name, path in corpus.items():
        _, sim, field = CORPUS[name]
        out = tmp_path / name
        code = main(_commands(path, good_run, out)[command])
        err = capsys.readouterr().err
        lines = [ln for ln in err.strip().splitlines() if ": warning:" not in ln]
        ok = (code == 2 and len(lines) == 1 and "Traceback" not in err
              and path.name in lines[0]
              and (sim is None or sim in lines[0]) and (field is None or field in lines[0]))
        if not ok:
            failures.append((name, code, err.strip()[-300:]))
        assert not any(p.is_file() for p in out.rglob("*")), (name, "wrote output")
    assert not failures, failures


def test_a_name_with_non_ascii_digits_is_readable(tmp_path, capsys):
    from dataset_factory import make_simulation

    from thrombojax.io.hdf5 import open_dataset, write_dataset

    path = write_dataset(tmp_path / "d.h5", [make_simulation("x1²"), make_simulation("x10")],
                         name="t", source="t")
    assert open_dataset(path).names == ["x1²", "x10"]
    assert main(["info", str(path)]) == 0
    assert "x1²" in capsys.readouterr().out
