"""``benchmarks/suite_compiles.py``: the plugin records a pytest run's compilations by program
and test, the report merges them with the run's durations, and refuses to overwrite."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))

import suite_compiles  # noqa: E402

TESTS = '''
import jax, jax.numpy as jnp

def test_one():
    @jax.jit
    def twice_plus_one(x):
        return 2 * x + 1
    assert float(twice_plus_one(jnp.ones(())) ) == 3.0
    assert float(jnp.sin(jnp.zeros(7)).sum()) == 0.0  # op by op: a small compile per op

def test_two():
    pass
'''


def _pytest(tmp_path, records, extra_env):
    (tmp_path / "test_tiny.py").write_text(TESTS)
    env = {k: v for k, v in os.environ.items() if k not in (suite_compiles.ENV,
                                                             "PYTEST_ADDOPTS")}
    env.update(PYTHONPATH=os.path.join(ROOT, "benchmarks"), JAX_PLATFORMS="cpu",
               JAX_COMPILATION_CACHE_DIR=str(tmp_path / "cache"), **extra_env)
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "suite_compiles",
                           "-p", "no:cacheprovider", "--durations=0", "test_tiny.py"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)


def test_records_every_compile_by_program_and_test_and_reports_them(tmp_path):
    records = tmp_path / "rec"
    proc = _pytest(tmp_path, records, {suite_compiles.ENV: str(records)})
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    programs, tests, n_proc, sites = suite_compiles.merge(records)
    assert n_proc == 1 and programs["jit_twice_plus_one"][0] == 1
    assert sites["test_tiny.py:9"][0] >= 1  # the eager line, attributed to itself
    assert tests["test_tiny.py::test_one"][0] >= 1 and "test_tiny.py::test_two" not in tests
    log = tmp_path / "run.log"
    log.write_text(proc.stdout)
    out = tmp_path / "report.md"
    argv = [str(records), "--log", str(log), "--out", str(out), "--suite-command", "pytest X"]
    assert suite_compiles.main(argv) == 0
    text = out.read_text()
    assert "| `jit_twice_plus_one` | 1 |" in text and "| test_tiny.py |" in text
    assert "worker-seconds" in text and "# jax:" in text and "# recorded run: pytest X" in text
    assert "The run: 2 passed" in text
    assert "| test_tiny.py:9 |" in text and "by the line that asked for them" in text
    with pytest.raises(SystemExit):
        suite_compiles.main(argv)  # the report exists: refused
    assert out.read_text() == text
    with pytest.raises(SystemExit):  # the run's log is an input: refused even forced
        suite_compiles.main([*argv[:3], "--out", str(log), "--force"])
    assert log.read_text() == proc.stdout
    assert suite_compiles.main([*argv, "--force"]) == 0


def test_refuses_to_run_without_a_records_folder(tmp_path):
    proc = _pytest(tmp_path, None, {})
    assert proc.returncode != 0
    assert suite_compiles.ENV in proc.stdout + proc.stderr
