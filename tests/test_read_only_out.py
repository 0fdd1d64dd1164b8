"""A read-only ``--out`` (issue 14, item 10): every writing command ends with one line naming
the path, exit status 2, no traceback, and the folder unchanged.

As a normal user the folder is really ``chmod 0o555``. Root ignores permissions, so there the
folder is made read-only by refusing, with ``PermissionError`` (EACCES) as the OS would, every
call that would create, open for writing, rename or remove something inside it (``open``,
``os.open``, ``os.mkdir``, ``os.replace`` / ``rename`` / ``unlink`` / ``rmdir``, writing
``h5py.File``); the test then also checks that a write was attempted and refused.
"""

from __future__ import annotations

import builtins
import contextlib
import errno
import io
import json
import os
import shutil
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest
from dataset_factory import accelerating_sims, make_simulation

from thrombojax.cli import main
from thrombojax.io.hdf5 import write_dataset

_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND


class _ReadOnly:
    """Refuse writes under ``root`` through the calls every writer goes through."""

    def __init__(self, root: Path, monkeypatch):
        self.root, self.denied = str(root.resolve()), []
        real_open, real_os_open, real_mkdir = builtins.open, os.open, os.mkdir
        real_file = h5py.File

        def inside(path) -> bool:
            if isinstance(path, int) or not isinstance(path, str | bytes | os.PathLike):
                return False
            full = os.path.abspath(os.fsdecode(path))
            return full == self.root or full.startswith(self.root + os.sep)

        def deny(path):
            self.denied.append(os.fsdecode(path))
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fsdecode(path))

        def fake_open(file, mode="r", *args, **kwargs):
            if inside(file) and any(c in mode for c in "wax+"):
                deny(file)
            return real_open(file, mode, *args, **kwargs)

        def fake_os_open(path, flags, *args, **kwargs):
            if inside(path) and flags & _WRITE_FLAGS:
                deny(path)
            return real_os_open(path, flags, *args, **kwargs)

        def fake_mkdir(path, *args, **kwargs):
            if inside(path) and not os.path.exists(path):
                deny(path)
            return real_mkdir(path, *args, **kwargs)

        def refuse(real):
            def call(*paths, **kwargs):
                for p in paths:
                    if inside(p):
                        deny(p)
                return real(*paths, **kwargs)
            return call

        class File(real_file):
            def __init__(self, name, mode="r", *args, **kwargs):
                if inside(name) and mode != "r":
                    deny(name)
                super().__init__(name, mode, *args, **kwargs)

        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)
        monkeypatch.setattr(os, "open", fake_os_open)
        monkeypatch.setattr(os, "mkdir", fake_mkdir)
        for name in ("replace", "rename", "unlink", "remove", "rmdir"):
            monkeypatch.setattr(os, name, refuse(getattr(os, name)))
        monkeypatch.setattr(h5py, "File", File)


@contextlib.contextmanager
def read_only_folder(folder: Path, monkeypatch):
    """Yield the emulator (root) or ``None`` (a real chmod 0o555 folder)."""
    folder.mkdir(exist_ok=True)
    if os.geteuid() == 0:
        with monkeypatch.context() as m:
            yield _ReadOnly(folder, m)
        return
    folder.chmod(0o555)
    try:
        yield None
    finally:
        folder.chmod(0o755)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    root = tmp_path_factory.mktemp("readonly")
    data = write_dataset(root / "d.h5", accelerating_sims(n_sims=3, n_nodes=60, n_frames=6),
                         name="d", source="t")
    run = root / "run"
    assert main(["train", "--dataset", str(data), "--model", "mgn", "--out", str(run), "--tiny",
                 "--epochs", "1", "--n-val", "1", "--batch-size", "2", "--warmup-epochs", "0",
                 "--quiet"]) == 0
    sim = make_simulation("r0")
    series = root / "series"
    series.mkdir()
    for t, frame in enumerate(sim.positions):
        meshio.write(series / f"frame_{t}.vtu",
                     meshio.Mesh(frame, [("tetra", sim.clot_cells), ("triangle", sim.wall_cells)]))
    run2 = root / "run2"  # a second member for `ensemble`: the same run under another seed
    shutil.copytree(run, run2)
    config = json.loads((run2 / "config.json").read_text())
    config["train"]["seed"] += 1
    (run2 / "config.json").write_text(json.dumps(config))
    return {"DATA": str(data), "RUN": str(run), "RUN2": str(run2), "SERIES": str(series)}


COMMANDS = {
    "generate": ["generate", "bendvessel-tiny", "--out", "RO/g.h5", "--sims", "1"],
    "import": ["import", "vtu", "SERIES", "--out", "RO/i.h5", "--units", "mm"],
    "train": ["train", "--dataset", "DATA", "--model", "mgn", "--out", "RO", "--tiny",
              "--epochs", "1", "--n-val", "1", "--batch-size", "2", "--warmup-epochs", "0"],
    "evaluate": ["evaluate", "--run", "RUN", "--dataset", "DATA", "--out", "RO"],
    "rollout": ["rollout", "--run", "RUN", "--dataset", "DATA", "--out", "RO", "--steps", "2",
                "--no-gif"],
    "export": ["export", "DATA", "--out", "RO"],
    "ensemble": ["ensemble", "RUN", "RUN2", "--out", "RO"],
    "bench": ["bench", "--models", "mgn", "--cases", "bendvessel", "--tiny", "--nodes", "64",
              "--max-steps", "2", "--repeats", "1", "--out", "RO"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_read_only_out_is_one_line_exit_2(command, inputs, tmp_path, monkeypatch, capsys):
    folder = tmp_path / "ro"
    names = {**inputs, "RO": str(folder)}
    argv = [names.get(a, a.replace("RO/", f"{folder}/")) for a in COMMANDS[command]]
    with read_only_folder(folder, monkeypatch) as emulated:
        capsys.readouterr()
        code = main([*argv, "--quiet"])
        listing = sorted(os.listdir(folder))
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"thrombojax {command}: error: ") and str(folder) in err, err
    assert "Permission denied" in err, err
    assert listing == [], listing  # nothing was written
    if emulated is not None:
        assert emulated.denied and all(str(folder) in p for p in emulated.denied)
    np.testing.assert_(Path(inputs["DATA"]).is_file())
