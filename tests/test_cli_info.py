"""`thrombojax info`: the summary, and one-line errors with exit 2 for every bad file."""

from __future__ import annotations

import subprocess
import sys

import pytest
from dataset_factory import BAD_FILES, make_simulation

from thrombojax.cli import main
from thrombojax.io.hdf5 import write_dataset


def test_info_prints_summary(tmp_path, capsys):
    sims = [make_simulation(f"sim_{i}", n_frames=5 + i, seed=i) for i in range(3)]
    path = write_dataset(tmp_path / "d.h5", sims, name="tiny", source="tests")
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "simulations: 3" in out and "name     tiny" in out and "source: tests" in out
    row = next(line for line in out.splitlines() if line.startswith("sim_2 "))
    assert row.split()[:6] == ["sim_2", "7", "13", "5", "38.5", "0.01"]  # frames nodes clot % dt
    assert "1.5" in row and "180.0" in row  # solver and reference wall times
    assert "clot fraction 0.385" in out
    assert "frames   5..7 per simulation, 18 in total" in out
    assert "bounding box (all simulations, all frames): [" in out
    assert "reference wall time (recorded): 540.0 s total over 3 simulations" in out
    assert "solver wall time (measured): 4.5 s total over 3 simulations, mean 1.5 s" in out


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_info_bad_files_exit_2_one_line(tmp_path, capsys, case):
    build, sim, field = BAD_FILES[case]
    path = build(tmp_path / f"{case}.h5")
    assert main(["info", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.startswith(f"thrombojax info: error: {path}") and err.count("\n") == 1
    assert "Traceback" not in err and captured.out == ""
    if sim is not None:
        assert f"simulation '{sim}'" in err
    if field is not None:
        assert f"field '{field}'" in err


def test_info_subprocess_missing_file(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "thrombojax", "info", str(tmp_path / "missing.h5")],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"thrombojax info: error: {tmp_path / 'missing.h5'}: no such file"


def test_help_texts(capsys):
    for argv in (["info", "--help"], ["import", "--help"], ["import", "vtu", "--help"],
                 ["import", "abaqus", "--help"]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 0
        assert "usage: thrombojax " + argv[0] in capsys.readouterr().out
