"""Where the test suite's time goes: every XLA compilation, timed and attributed.

The suite's time is mostly compiling small programs (``tests/conftest.py``). This module is both
a pytest plugin that records, in each pytest process (each xdist worker), every backend
compilation that misses the persistent cache (its program name, the test that ran it, the
wall time of the compile), and a script that merges those records into tables: totals, the
programs that cost most, the test files that cost most, the wall time of each file beside
its compile time when the run printed ``--durations=0``, and the lines that asked for the
small compilations (under 0.15 s each: mostly JAX running a function op by op, each operation
compiled on its own, where one ``jax.jit`` would compile the whole once).

Compilations in subprocesses (the kill trials, the demo, the notebook) are not recorded: they
run other interpreters. The wrapped function is JAX's private
``jax._src.compiler.backend_compile_and_load``; under a JAX without it the plugin refuses to
start rather than record nothing.

Usage (any pytest command line; the records go to ``$THROMBOJAX_COMPILE_RECORDS``)::

    THROMBOJAX_COMPILE_RECORDS=/tmp/rec PYTHONPATH=benchmarks .venv/bin/python -m pytest -q \
        -n 2 --dist loadfile --no-loadscope-reorder --durations=0 -p suite_compiles \
        2>&1 | tee suite.log
    python benchmarks/suite_compiles.py /tmp/rec [--log suite.log] [--top 25] [--out FILE]

or ``PYTEST_ADDOPTS="-p suite_compiles" make test`` (its log holds the 30 slowest tests'
durations only).
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import pathlib
import re
import sys
import time
import traceback

ENV = "THROMBOJAX_COMPILE_RECORDS"
_BY_PROGRAM: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
_BY_TEST: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
_BY_SITE: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
_CURRENT = ["(outside tests)"]
_ROOT = [""]
SMALL_S = 0.15  # a compile under this is counted by its call site (mostly eager operations)


def _site() -> str:
    """The line of the test file that asked for a compile and the innermost line under the
    run's root (the package, a test helper) below it, ``test_x.py:12 -> pkg/mod.py:34``."""
    ours = [f for f in traceback.extract_stack()[:-2]
            if f.filename.startswith(_ROOT[0]) and "site-packages" not in f.filename]
    if not ours:
        return "(outside the run's files)"

    def where(frame) -> str:
        return f"{os.path.relpath(frame.filename, _ROOT[0])}:{frame.lineno}"

    test = next((f for f in ours if os.path.basename(f.filename).startswith("test_")), ours[0])
    return where(test) if test is ours[-1] else f"{where(test)} -> {where(ours[-1])}"


def _program_name(module) -> str:
    try:
        return str(module.operation.attributes["sym_name"]).strip('"')
    except (AttributeError, KeyError):
        return "(unnamed)"


def install() -> None:
    """Wrap JAX's backend compile so that every call is timed (idempotent)."""
    try:
        from jax._src import compiler
        original = compiler.backend_compile_and_load
    except (ImportError, AttributeError) as err:
        import jax
        raise RuntimeError(f"suite_compiles: jax {jax.__version__} has no "
                           "jax._src.compiler.backend_compile_and_load to time") from err
    if getattr(original, "_suite_compiles", False):
        return

    def timed(backend, module, *args, **kwargs):
        start = time.perf_counter()
        try:
            return original(backend, module, *args, **kwargs)
        finally:
            seconds = time.perf_counter() - start
            keys = [(_BY_PROGRAM, _program_name(module)), (_BY_TEST, _CURRENT[0])]
            if seconds < SMALL_S:
                keys.append((_BY_SITE, _site()))
            for table, key in keys:
                table[key][0] += 1
                table[key][1] += seconds

    timed._suite_compiles = True
    compiler.backend_compile_and_load = timed


# -- pytest plugin hooks ----------------------------------------------------------------------

def pytest_configure(config) -> None:
    if not os.environ.get(ENV):
        raise RuntimeError(f"suite_compiles: set {ENV} to the folder for the records")
    _ROOT[0] = str(config.rootpath) + os.sep
    install()


def pytest_runtest_setup(item) -> None:
    _CURRENT[0] = item.nodeid


def pytest_unconfigure(config) -> None:  # noqa: ARG001
    folder = pathlib.Path(os.environ[ENV])
    folder.mkdir(parents=True, exist_ok=True)
    record = {"pid": os.getpid(), "by_program": dict(_BY_PROGRAM), "by_test": dict(_BY_TEST),
              "by_site": dict(_BY_SITE)}
    from thrombojax.io.outputs import atomic_write_text

    atomic_write_text(folder / f"compiles.{os.getpid()}.json", json.dumps(record))


# -- the report -------------------------------------------------------------------------------

def merge(folder: pathlib.Path) -> tuple[dict, dict, int, dict]:
    """Sum the records of every process under ``folder``: (by program, by test, processes,
    small compilations by call site)."""
    files = sorted(folder.glob("compiles.*.json"))
    if not files:
        raise SystemExit(f"suite_compiles: no compiles.*.json under {folder}")
    programs: dict = collections.defaultdict(lambda: [0, 0.0])
    tests: dict = collections.defaultdict(lambda: [0, 0.0])
    sites: dict = collections.defaultdict(lambda: [0, 0.0])
    for path in files:
        record = json.loads(path.read_text())
        for table, key in ((programs, "by_program"), (tests, "by_test"), (sites, "by_site")):
            for name, (count, seconds) in record.get(key, {}).items():
                table[name][0] += count
                table[name][1] += seconds
    return dict(programs), dict(tests), len(files), dict(sites)


def durations(log: pathlib.Path) -> dict[str, float]:
    """Per-file wall seconds (setup + call + teardown) from pytest's ``--durations`` lines."""
    out: dict[str, float] = collections.defaultdict(float)
    pattern = re.compile(r"^\s*([\d.]+)s (?:call|setup|teardown)\s+(\S+?)::")
    for line in log.read_text(errors="replace").splitlines():
        if m := pattern.match(line):
            out[m.group(2)] += float(m.group(1))
    return dict(out)


def _summary(log: pathlib.Path) -> str | None:
    """The log's last pytest summary (``866 passed, 1 warning in 2292.93s``) and, when the
    run was under ``time``, its real / user / sys lines."""
    text = log.read_text(errors="replace")
    found = re.findall(r"^=* ?(\d+ passed.* in [\d.]+s[^=\n]*)", text, re.MULTILINE)
    times = re.findall(r"^(real|user|sys)\s+(\S+)$", text, re.MULTILINE)
    if not found:
        return None
    return found[-1].strip() + "".join(f"; {k} {v}" for k, v in times[-3:])


def report(folder: pathlib.Path, log: pathlib.Path | None, top: int) -> list[str]:
    """The report's markdown lines."""
    programs, tests, n_proc, sites = merge(folder)
    total = sum(s for _, s in programs.values())
    count = sum(c for c, _ in programs.values())
    small = sum(s for c, s in programs.values() if s / c < SMALL_S)
    lines = [f"{count} compilations in {n_proc} pytest processes: {total:.0f} s "
             f"({small:.0f} s in programs of under {SMALL_S} s on average: mostly eager "
             "operations)",
             "", "| program | compiles | seconds | s / compile |", "|---|---|---|---|"]
    for name, (c, s) in sorted(programs.items(), key=lambda kv: -kv[1][1])[:top]:
        lines.append(f"| `{name}` | {c} | {s:.1f} | {s / c:.2f} |")
    files: dict = collections.defaultdict(lambda: [0, 0.0])
    for nodeid, (c, s) in tests.items():
        files[nodeid.split("::")[0]][0] += c
        files[nodeid.split("::")[0]][1] += s
    walls = durations(log) if log else {}
    summary = _summary(log) if log else None
    if summary:
        lines += ["", f"The run: {summary}"]
    if walls:
        lines += ["", f"Wall time in the log's duration lines: {sum(walls.values()):.0f} "
                  "worker-seconds (every test's only when the run printed --durations=0; a "
                  "file without lines: -)."]
    lines += ["", "| test file | compiles | compile s | wall s |", "|---|---|---|---|"]
    order = sorted(set(files) | set(walls),
                   key=lambda f: -max(files.get(f, [0, 0.0])[1], walls.get(f, 0.0)))
    for name in order[:top]:
        c, s = files.get(name, [0, 0.0])
        wall = f"{walls[name]:.0f}" if name in walls else "-"
        lines.append(f"| {name} | {c} | {s:.0f} | {wall} |")
    if sites:
        lines += ["", f"Compilations of under {SMALL_S} s each, by the line that asked for them "
                  "(the test's line -> the innermost line of the run's files below it):", "",
                  "| call site | compiles | seconds |", "|---|---|---|"]
        for name, (c, s) in sorted(sites.items(), key=lambda kv: -kv[1][1])[:top]:
            lines.append(f"| {name} | {c} | {s:.1f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("records", type=pathlib.Path, help=f"the folder of ${ENV}")
    parser.add_argument("--log", type=pathlib.Path,
                        help="the run's output, with pytest's --durations=0 lines")
    parser.add_argument("--suite-command", default="",
                        help="the command of the recorded run, written into the report")
    parser.add_argument("--top", type=int, default=25, help="rows per table")
    parser.add_argument("--out", type=pathlib.Path, help="also write the report here")
    parser.add_argument("--force", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    from thrombojax.eval.tables import environment
    from thrombojax.io.outputs import atomic_write_text, refuse_targets

    refuse_targets(parser, (args.out,), force=args.force, what="report",
                   inputs=[args.log] if args.log else ())
    env = environment()
    lines = ["# benchmarks/suite_compiles.py: XLA compilations of the test suite", "", "```",
             *[f"# {k}: {v}" for k, v in env.items()],
             *([f"# recorded run: {args.suite_command}"] if args.suite_command else []),
             "```", "",
             *report(args.records, args.log, args.top)]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out:
        atomic_write_text(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
