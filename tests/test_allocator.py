"""The command runs itself under tcmalloc when installed, once, unless the user opts out."""

import os
import subprocess
import sys

import pytest

from thrombojax.cli.allocator import OPT_OUT, find_tcmalloc, preload_environment

LIB = "/usr/lib/x86_64-linux-gnu/libtcmalloc_minimal.so.4"
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # the repository


def _clean_environment(pythonpath: str, **extra) -> dict:
    """This process's environment without a preload or the opt-out, plus ``extra``."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", OPT_OUT)}
    return {**env, "PYTHONPATH": pythonpath, **extra}


def test_preload_environment_prepends_the_library():
    env = preload_environment({"PATH": "/bin", "LD_PRELOAD": "/x/libfoo.so"}, LIB)
    assert env == {"PATH": "/bin", "LD_PRELOAD": f"{LIB}:/x/libfoo.so"}
    assert preload_environment({}, LIB) == {"LD_PRELOAD": LIB}


@pytest.mark.parametrize("environ, library", [
    ({}, None),  # not installed
    ({"LD_PRELOAD": LIB}, LIB),  # already preloaded: no second re-exec
    ({"LD_PRELOAD": "/opt/libtcmalloc.so"}, LIB),  # the user's own tcmalloc
    ({OPT_OUT: "1"}, LIB),  # opted out
])
def test_no_reexec_when_not_due(environ, library):
    assert preload_environment(environ, library) is None


def test_find_tcmalloc_searches_the_given_dirs(tmp_path):
    assert find_tcmalloc([str(tmp_path)]) is None
    (tmp_path / "libtcmalloc.so.4").write_bytes(b"")
    assert find_tcmalloc([str(tmp_path / "none"), str(tmp_path)]) == str(
        tmp_path / "libtcmalloc.so.4")


def _command_under(extra_env, tmp_path):
    """Run `python -m thrombojax info /nonexistent.h5` (exits 2); a sitecustomize hook prints
    at exit whether tcmalloc is mapped in the process that finally ran the command."""
    (tmp_path / "sitecustomize.py").write_text(
        "import atexit, sys\n"
        "atexit.register(lambda: sys.stderr.write("
        "'MAPS %s\\n' % ('tcmalloc' in open('/proc/self/maps').read())))\n"
        "atexit.register(lambda: sys.stderr.write('ARGV0 %s\\n' % sys.argv[0]))\n")
    env = _clean_environment(os.pathsep.join([str(tmp_path), ROOT]), **extra_env)
    return subprocess.run([sys.executable, "-m", "thrombojax", "info", "/nonexistent.h5"],
                          env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.skipif(find_tcmalloc() is None or not sys.platform.startswith("linux"),
                    reason="tcmalloc is not installed here")
def test_command_reexecs_under_tcmalloc_and_opt_out_works(tmp_path):
    on = _command_under({}, tmp_path)
    assert on.returncode == 2 and "MAPS True" in on.stderr, on.stderr
    assert on.stderr.count("no such file") == 1  # the command ran once
    # the re-executed process keeps the program name (results record the command as run)
    assert "ARGV0 -c" not in on.stderr and "__main__.py" in on.stderr, on.stderr
    off = _command_under({OPT_OUT: "1"}, tmp_path)
    assert off.returncode == 2 and "MAPS False" in off.stderr, off.stderr


@pytest.mark.skipif(find_tcmalloc() is None or not sys.platform.startswith("linux"),
                    reason="tcmalloc is not installed here")
def test_script_reexecs_under_tcmalloc_once_with_its_arguments(tmp_path):
    script = tmp_path / "job.py"
    script.write_text(
        "import sys\n"
        "from thrombojax.cli.allocator import reexec_script_with_tcmalloc\n"
        "if __name__ == '__main__':\n"
        "    print('START', flush=True)\n"
        "    reexec_script_with_tcmalloc(sys.argv[0], sys.argv[1:])\n"
        "    print('MAPS', 'tcmalloc' in open('/proc/self/maps').read(), sys.argv[1:])\n")
    def run(**extra):
        return subprocess.run([sys.executable, str(script), "--a", "b c"],
                              env=_clean_environment(ROOT, **extra),
                              capture_output=True, text=True, timeout=120).stdout

    on = run()
    assert on.count("START") == 2 and "MAPS True ['--a', 'b c']" in on, on  # one re-exec
    off = run(**{OPT_OUT: "1"})
    assert off.count("START") == 1 and "MAPS False ['--a', 'b c']" in off, off
