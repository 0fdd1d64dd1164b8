"""Shared machinery of the kill -9 trial modules (``tests/test_kill_trials_*.py``, issue 14).

A trial starts a real ``thrombojax`` command in a subprocess and sends it SIGKILL at a random
time drawn uniformly between the interpreter's start-up time and the command's uninterrupted
duration (both measured first; a trial that finishes before its kill time replaces the duration
by its own, so later trials land inside the run). After every trial each file at a target
path must open (HDF5, JSON / JSONL, PNG / GIF, XDMF / VTU), and the inputs must be unchanged
(SHA-256 before and after). After the trials one more uninterrupted run of the same command
must leave no temporary in the output folder.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import random
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterable
from pathlib import Path

import h5py
from PIL import Image

__all__ = ["TRIALS", "TEMP_MARKS", "TrialReport", "run_kill_trials", "temporaries", "opens",
           "checksums", "complete_files"]

TRIALS = 20  # issue 14: 20 kill -9 trials per command
TEMP_MARKS = (".tjxtmp-", "orbax-checkpoint-tmp")  # ours (thrombojax/io/outputs.py), orbax's
REPO = Path(__file__).resolve().parents[1]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg", "JAX_PLATFORMS": "cpu"}


def _is_temporary(path: Path, root: Path) -> bool:
    return any(m in part for part in path.relative_to(root).parts for m in TEMP_MARKS)


def temporaries(folder: Path) -> list[Path]:
    """Every temporary (ours or orbax's) anywhere under ``folder``."""
    return [p for p in folder.rglob("*") if any(m in p.name for m in TEMP_MARKS)]


def opens(path: Path) -> None:
    """Raise unless ``path`` is complete for its kind (unknown kinds are read whole)."""
    name = path.name
    if name.endswith(".h5"):
        with h5py.File(path, "r") as f:
            f.visit(lambda _: None)
    elif name.endswith((".xdmf", ".pvd", ".vtu")):
        ET.parse(path)
    elif name.endswith((".png", ".gif")):
        with Image.open(path) as im:
            for frame in range(getattr(im, "n_frames", 1)):
                im.seek(frame)
                im.load()
    elif name.endswith(".json"):
        json.loads(path.read_text())
    elif name.endswith(".jsonl"):
        for line in path.read_text().splitlines():
            if line.strip():
                json.loads(line)
    else:
        path.read_bytes()


def complete_files(folder: Path) -> list[Path]:
    """Open every file at a target path under ``folder`` (temporaries excluded); returns them."""
    files = [p for p in folder.rglob("*") if p.is_file() and not _is_temporary(p, folder)
             and "checkpoints" not in p.relative_to(folder).parts]
    for path in files:
        opens(path)
    return files


def checksums(paths: Iterable[Path]) -> dict[str, str]:
    """SHA-256 of every file under ``paths`` (files or folders, recursively)."""
    out = {}
    for root in paths:
        for p in ([root] if root.is_file() else sorted(root.rglob("*"))):
            if p.is_file():
                out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _run(argv: list[str]) -> float:
    """Run ``thrombojax ARGV`` to completion; returns its wall time (fails on a non-zero exit)."""
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "thrombojax", *argv], env=_env(),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, (argv, proc.stderr[-2000:])
    return time.perf_counter() - start


def _kill_at(argv: list[str], at: float) -> float | None:
    """Start ``thrombojax ARGV`` and SIGKILL it ``at`` seconds later. Returns ``None`` when it
    was killed, else (it had finished, and must have succeeded) its wall time."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "thrombojax", *argv], env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        proc.wait(timeout=at)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stderr.close()
        return None
    elapsed = time.perf_counter() - start
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    assert proc.returncode == 0, (argv, err[-2000:])
    return elapsed


@dataclasses.dataclass
class TrialReport:
    """What the trials of one command did (for assertions and the failure messages)."""

    startup_s: float
    duration_s: float
    kill_times: list[float]
    killed: int


def run_kill_trials(
    argv: list[str], out: Path, inputs: list[Path], *, seed: int,
    check: Callable[[Path], None] | None = None, trials: int = TRIALS,
) -> TrialReport:
    """``trials`` kill -9 trials of ``thrombojax ARGV`` (which must carry ``--force``).

    Args:
        argv: the command; it writes under ``out``.
        out: the output file's folder or the output folder.
        inputs: files / folders the command must leave byte-identical.
        seed: seed of the kill times (a failure message names the trial and its time).
        check: an extra completeness check of ``out`` after each trial (e.g. checkpoints).
    """
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "thrombojax", "--version"], env=_env(), check=True,
                   capture_output=True)
    startup = time.perf_counter() - start
    duration = _run(argv)
    before = checksums(inputs)
    rng = random.Random(seed)
    times, killed = [], 0
    for trial in range(trials):
        at = rng.uniform(startup, duration)
        times.append(at)
        finished = _kill_at(argv, at)
        killed += finished is None
        if finished is not None:  # the first run was slower (a cold cache, a busy machine)
            duration = max(finished, startup + 0.1)
        where = f"trial {trial} of {argv[0]}, SIGKILL at {at:.2f} s of {duration:.2f} s"
        try:
            complete_files(out)
            if check is not None:
                check(out)
        except Exception as err:
            raise AssertionError(f"{where}: a file at a target path does not open: {err}") from err
        assert checksums(inputs) == before, f"{where}: an input changed"
    _run(argv)  # the next uninterrupted run removes what the killed ones left
    assert not temporaries(out), temporaries(out)
    complete_files(out)
    assert checksums(inputs) == before
    return TrialReport(startup, duration, times, killed)


def tiny_dataset(path: Path, n_sims: int = 3) -> Path:
    """Generate a ``bendvessel-tiny`` dataset of ``n_sims`` simulations at ``path`` (in process)."""
    from thrombojax.cli import main

    assert main(["generate", "bendvessel-tiny", "--out", str(path), "--sims", str(n_sims),
                 "--quiet"]) == 0
    return path
