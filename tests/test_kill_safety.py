"""kill -9 in the middle of a real command's write never leaves a file at a target path that does
not open, and the next writing run in that folder removes the orphaned temporary."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import pytest
from dataset_factory import make_simulation
from PIL import Image

from thrombojax.cli import main
from thrombojax.io.hdf5 import write_dataset

REPO = Path(__file__).resolve().parents[1]


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if ".tjxtmp-" in p.name]


def opens(path: Path) -> None:
    """Raise unless the file is complete for its kind."""
    name = path.name
    if name.endswith(".h5"):
        with h5py.File(path, "r") as f:
            list(f)
    elif name.endswith((".xdmf", ".pvd", ".vtu")):
        ET.parse(path)
    elif name.endswith((".png", ".gif")):
        with Image.open(path) as im:
            im.load()
    elif name.endswith(".json"):
        json.loads(path.read_text())


def kill_while_writing(argv: list[str], folder: Path, after: int = 1,
                       timeout: float = 120.0, tag: str = ".tjxtmp-") -> bool:
    """Start ``thrombojax ARGV``; SIGKILL it as soon as the ``after``-th distinct temporary
    appears in ``folder``. Returns whether it was killed mid-write (else it finished first)."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    proc = subprocess.Popen([sys.executable, "-m", "thrombojax", *argv], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + timeout
    killed, seen = False, set()
    while proc.poll() is None and time.monotonic() < deadline:
        try:  # the command renames and removes its temporaries while we look
            seen |= {p for p in folder.rglob("*") if tag in p.name}
        except FileNotFoundError:
            pass
        if len(seen) >= after:
            proc.send_signal(signal.SIGKILL)
            killed = True
            break
        time.sleep(0.002)
    if proc.poll() is None and not killed:
        proc.kill()
    proc.wait()
    return killed


def check_targets_and_cleanup(folder: Path, tmp_path: Path) -> None:
    for path in folder.rglob("*"):
        if path.is_file() and ".tjxtmp-" not in str(path.relative_to(folder)):
            opens(path)
    small = write_dataset(tmp_path / "small.h5", [make_simulation("s")], name="s", source="t")
    assert main(["export", str(small), "--out", str(folder), "--quiet", "--force"]) == 0
    assert not temporaries(folder)


@pytest.mark.parametrize("after", [1, 3])
def test_kill_export(tmp_path, after):
    sims = [make_simulation(f"sim_{i}", n_frames=60, seed=i) for i in range(6)]
    data = write_dataset(tmp_path / "d.h5", sims, name="d", source="t")
    out = tmp_path / "ex"
    killed = kill_while_writing(["export", str(data), "--out", str(out), "--format", "vtu",
                                 "--quiet"], out, after=after)
    assert killed, "the export finished before any temporary was seen"
    check_targets_and_cleanup(out, tmp_path)


@pytest.mark.parametrize("plot", [False, True])
def test_kill_generate(tmp_path, plot):
    out = tmp_path / "gen"
    target = out / "g.h5"
    argv = ["generate", "bendvessel-tiny", "--out", str(target), "--sims", "1", "--quiet"]
    killed = kill_while_writing(argv + (["--plot"] if plot else []), out)
    assert killed
    assert not target.exists()  # the dataset only appears complete
    check_targets_and_cleanup(out, tmp_path)


@pytest.mark.slow
def test_kill_train_mid_checkpoint_then_resume_and_kill_rollout(tmp_path):
    from thrombojax.train.state import load_trained, read_run_config

    sims = [make_simulation(f"sim_{i}", n_frames=8, seed=i) for i in range(3)]
    data = write_dataset(tmp_path / "d.h5", sims, name="d", source="t")
    run = tmp_path / "run"
    train_argv = ["train", "--dataset", str(data), "--model", "mgn", "--out", str(run),
                  "--tiny", "--epochs", "2", "--n-val", "1", "--batch-size", "1",
                  "--warmup-epochs", "0", "--quiet"]
    assert kill_while_writing(train_argv, run, tag="orbax-checkpoint-tmp")
    read_run_config(run)  # config.json is complete
    assert main([*train_argv, "--resume"]) == 0  # continues (or restarts) from what is on disk
    load_trained(run, which="best")
    out = tmp_path / "ro"
    ro_argv = ["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
               "--split", "all", "--skip", "2", "--quiet"]
    assert kill_while_writing(ro_argv, out, after=4)
    check_targets_and_cleanup(out, tmp_path)
