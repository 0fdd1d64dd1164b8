"""Nothing lost: inputs never overwritten, outputs replaced only with --force, atomic writes,
collision-free names, and kill -9 never leaves a broken file at a target path."""

from __future__ import annotations

import argparse
import hashlib
import os
import random
import signal
import subprocess
import sys
import textwrap
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import pytest
from dataset_factory import make_simulation

from thrombojax.cli import main
from thrombojax.errors import OutputError
from thrombojax.io.hdf5 import open_dataset, write_dataset
from thrombojax.io.outputs import (
    atomic_path,
    check_target,
    clean_temporaries,
    fresh_owned_folder,
    refuse_targets,
    safe_stem,
    safe_stems,
)

REPO = Path(__file__).resolve().parents[1]


def sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def dataset(path: Path, *names: str) -> Path:
    sims = [make_simulation(n, seed=i) for i, n in enumerate(names)]
    return write_dataset(path, sims, name=path.stem, source="test")


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if ".tjxtmp-" in p.name]


def test_export_next_to_dataset_named_like_its_simulation_keeps_the_dataset(tmp_path):
    data = dataset(tmp_path / "run1.h5", "run1")  # the usual name after `import ... run1.h5`
    before = sha(data)
    assert main(["export", str(data), "--out", str(tmp_path), "--quiet"]) == 0
    assert sha(data) == before
    assert open_dataset(data).names == ["run1"]
    xdmf = tmp_path / "run1.xdmf"
    ET.parse(xdmf)  # well formed
    with h5py.File(tmp_path / "run1.xdmf.h5") as f:
        assert f["geometry"]["00000"].shape == (13, 3)


def test_dotted_names_give_one_series_each(tmp_path):
    names = ["flow_0.5", "flow_1.5", "flow_1.25", "Flow_1.25"]
    data = dataset(tmp_path / "d.h5", *names)
    out = tmp_path / "ex"
    assert main(["export", str(data), "--out", str(out), "--quiet"]) == 0
    series = sorted(p.name for p in out.glob("*.xdmf"))
    assert len(series) == len(names)
    assert len({s.casefold() for s in series}) == len(names)
    for vtu_run in (out / "vtu",):
        assert main(["export", str(data), "--out", str(vtu_run), "--format", "vtu",
                     "--quiet"]) == 0
        assert len(list(vtu_run.glob("*.pvd"))) == len(names)


@pytest.mark.parametrize("name", ["..", ".", "a/b", "a\\b", "c:d", "CON", "nul.txt", "com1",
                                  "x1²", " lead", "trail.", "flow_0.5", "ok-name_1"])
def test_safe_stem_stays_in_the_folder(name, tmp_path):
    stem = safe_stem(name)
    assert stem and "/" not in stem and "\\" not in stem and ":" not in stem
    assert not stem.startswith(".") and not stem.endswith(".")
    assert stem.split(".")[0].upper() not in {"CON", "NUL", "COM1"}
    assert (tmp_path / stem).resolve().parent == tmp_path.resolve()
    if name in ("flow_0.5", "ok-name_1"):
        assert stem == name  # safe names are kept as they are


def test_safe_stems_never_collide():
    names = ["a/b", "a_b", "a:b", "A_B", "CON", "_CON", "..", "_", "x", "X"]
    stems = safe_stems(names)
    assert len({s.casefold() for s in stems.values()}) == len(names)


def test_existing_outputs_need_force_and_inputs_never_replaced(tmp_path):
    data = dataset(tmp_path / "d.h5", "s")
    out = tmp_path / "ex"
    argv = ["export", str(data), "--out", str(out), "--quiet"]
    assert main(argv) == 0
    first = sha(out / "s.xdmf.h5")
    assert main(argv) == 2  # exists, no --force
    assert sha(out / "s.xdmf.h5") == first
    assert main([*argv, "--force"]) == 0
    with pytest.raises(OutputError, match="input"):
        check_target(data, inputs=[data], force=True)
    link = tmp_path / "link.h5"
    os.link(data, link)
    with pytest.raises(OutputError, match="input"):
        check_target(link, inputs=[data], force=True)


def test_refuse_targets_is_a_usage_error_naming_the_file_and_force(tmp_path, capsys):
    """The benchmark scripts' check (thrombojax.io.outputs.refuse_targets): options not given
    are skipped, an existing report is refused unless forced, two options naming one file
    are refused even forced, and an input never."""
    parser = argparse.ArgumentParser(prog="bench")
    report, data = tmp_path / "r.md", tmp_path / "in.json"
    assert refuse_targets(parser, (None, report)) == [report]
    report.write_text("weeks of timings")
    data.write_text("{}")
    for targets, kwargs, message in [
            ((report,), {}, "r.md: report already exists; pass --force to replace it"),
            ((report, tmp_path / "R.md"), {"force": True}, "share this file name"),
            ((data,), {"force": True, "inputs": [data]}, "would overwrite the input")]:
        with pytest.raises(SystemExit) as exc:
            refuse_targets(parser, targets, what="report", **kwargs)
        assert exc.value.code == 2 and message in capsys.readouterr().err
    assert refuse_targets(parser, (report,), force=True) == [report]
    assert report.read_text() == "weeks of timings"


def test_import_refuses_to_write_over_its_source(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "f0.vtu").write_text("not read")
    before = sha(frames / "f0.vtu")
    code = main(["import", "vtu", str(frames), "--out", str(frames / "f0.vtu"), "--force",
                 "--units", "mm", "--quiet"])
    assert code == 2
    assert sha(frames / "f0.vtu") == before


def test_generate_refuses_existing_dataset_and_plot_over_dataset(tmp_path, capsys):
    precious = dataset(tmp_path / "precious.h5", *[f"s{i}" for i in range(6)])
    before = sha(precious)
    assert main(["generate", "bendvessel-tiny", "--out", str(precious), "--sims", "1",
                 "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    assert sha(precious) == before
    png = tmp_path / "ds.png"
    assert main(["generate", "bendvessel-tiny", "--out", str(png), "--plot", "--quiet"]) == 2
    assert not png.exists()


def test_atomic_path_removes_its_temporary_on_failure(tmp_path):
    target = tmp_path / "x.json"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("partial")
        raise RuntimeError("writer failed")
    assert not target.exists() and not temporaries(tmp_path)
    with atomic_path(target) as tmp:
        tmp.write_text("{}")
    assert target.read_text() == "{}" and not temporaries(tmp_path)


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    pid = int(dead.stdout)
    stale = tmp_path / f".d.h5.tjxtmp-{pid}-0123abcd.tmp"
    stale.write_bytes(b"junk")
    mine = tmp_path / f".e.h5.tjxtmp-{os.getpid()}-0123abcd.tmp"  # a live writer's
    mine.write_bytes(b"in use")
    # a killed GIF write: a temporary of a temporary, plus PillowWriter's ".gif"
    nested = tmp_path / (f"..r.gif.tjxtmp-{pid}-be718baa.gif.tjxtmp-{pid}-ce2f7cc7.gif.gif")
    nested.write_bytes(b"half a gif")
    other = tmp_path / ".hidden.tmp"  # not ours
    other.write_bytes(b"keep")
    assert sorted(clean_temporaries(tmp_path)) == sorted([stale, nested])
    assert mine.exists() and other.exists()


_WRITER = textwrap.dedent("""
    import sys, h5py, numpy as np
    from pathlib import Path
    from thrombojax.io.outputs import atomic_path
    target = Path(sys.argv[1])
    for round in range(1000):
        with atomic_path(target) as tmp, h5py.File(tmp, "w") as f:
            for i in range(40):
                f[f"a{i}"] = np.full((20000,), round, np.float32)
        print(round, flush=True)
""")


def test_kill_9_never_leaves_a_broken_file_at_the_target(tmp_path):
    rng = random.Random(14)
    target = tmp_path / "out.h5"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    for _ in range(6):
        proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(target)], env=env,
                                stdout=subprocess.PIPE, text=True)
        proc.stdout.readline() if rng.random() < 0.5 else None  # sometimes after a full file
        time.sleep(rng.uniform(0.0, 0.3))
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
        if target.exists():
            with h5py.File(target) as f:  # opens and holds a complete round
                assert len(f) == 40 and len({float(f[k][0]) for k in f}) == 1
    with atomic_path(tmp_path / "next.txt") as tmp:  # the next run cleans up
        tmp.write_text("x")
    assert not temporaries(tmp_path)


def test_broken_pipe_is_not_a_traceback(tmp_path):
    data = dataset(tmp_path / "d.h5", "s")
    read_end, write_end = os.pipe()
    os.close(read_end)  # `| head` that already left
    proc = subprocess.run([sys.executable, "-m", "thrombojax", "info", str(data)],
                          stdout=write_end, stderr=subprocess.PIPE, text=True,
                          env={**os.environ, "PYTHONPATH": str(REPO)}, cwd=tmp_path)
    os.close(write_end)
    assert "Traceback" not in proc.stderr
    assert proc.returncode == 0


@pytest.mark.parametrize("command", ["export", "generate"])
def test_unwritable_output_is_one_line(tmp_path, capsys, command):
    data = dataset(tmp_path / "d.h5", "s")
    blocked = tmp_path / "a_file"  # a file where a folder is needed: OSError for root too
    blocked.write_text("")
    argv = {"export": ["export", str(data), "--out", str(blocked / "x"), "--quiet"],
            "generate": ["generate", "bendvessel-tiny", "--out", str(blocked / "g.h5"),
                         "--quiet"]}[command]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(blocked) in err[0]


def test_demo_folder_never_removes_a_users_folder(tmp_path):
    user = tmp_path / "results"
    user.mkdir()
    (user / "weeks_of_work.h5").write_bytes(b"precious")
    with pytest.raises(OutputError, match="not written by thrombojax demo"):
        fresh_owned_folder(user, "demo")
    assert (user / "weeks_of_work.h5").read_bytes() == b"precious"
    demo = fresh_owned_folder(tmp_path / "demo_output", "demo")
    (demo / "old.png").write_bytes(b"x")
    fresh_owned_folder(demo, "demo")  # its own folder: replaced whole
    assert not (demo / "old.png").exists() and (demo / ".thrombojax-demo").is_file()
