"""Run the ``thrombojax`` command under tcmalloc when the machine has it.

Why: under glibc's malloc, XLA's per-step temporaries above glibc's mmap threshold are mapped
afresh on every call and zero-filled by the kernel page by page, so a MeshGraphNet training step
on the CPU spends most of its time in minor page faults (``benchmarks/train_step.py`` prints the
faults per step with and without). tcmalloc keeps freed pages mapped and reuses them.

How: an allocator must be loaded before the process starts allocating, i.e. with ``LD_PRELOAD``
at ``exec`` time; setting it from inside a running Python is too late. So the console command
re-executes itself once (the same interpreter and the same thrombojax package, ``ARGS``
unchanged) with ``LD_PRELOAD`` naming tcmalloc, when

* the library is installed (Debian/Ubuntu package ``libtcmalloc-minimal4``; the paths in
  :data:`SEARCH_DIRS`), and
* ``LD_PRELOAD`` does not name a tcmalloc already (which is also what stops a second re-exec),
* and ``THROMBOJAX_NO_TCMALLOC`` is not ``1`` (the opt-out).

This is done by the command (not only by ``make``) so that every way of running it gets it:
the console script, ``python -m thrombojax``, a job script, a ``make`` target. Library users who
import thrombojax in their own processes preload it themselves: ``docs/performance.md``.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping, Sequence

__all__ = ["LIBRARY_NAMES", "SEARCH_DIRS", "OPT_OUT", "find_tcmalloc", "preload_environment",
           "reexec_with_tcmalloc", "reexec_script_with_tcmalloc"]

LIBRARY_NAMES: tuple[str, ...] = ("libtcmalloc_minimal.so.4", "libtcmalloc.so.4")
"""tcmalloc builds to look for, preferred first (the minimal one has no heap profiler)."""
SEARCH_DIRS: tuple[str, ...] = (
    "/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib",
    "/usr/local/lib",
)
"""Directories searched, in order."""
OPT_OUT: str = "THROMBOJAX_NO_TCMALLOC"
"""Set to ``1`` to run the command under the default allocator."""


def find_tcmalloc(dirs: Sequence[str] = SEARCH_DIRS) -> str | None:
    """Path of an installed tcmalloc shared library, or None."""
    for directory in dirs:
        for name in LIBRARY_NAMES:
            path = os.path.join(directory, name)
            if os.path.isfile(path):
                return path
    return None


def preload_environment(environ: Mapping[str, str], library: str | None) -> dict | None:
    """The environment to re-execute with, or None when no re-exec is due.

    Args:
        environ: the current environment.
        library: the tcmalloc path (:func:`find_tcmalloc`), or None when absent.
    Returns:
        A copy of ``environ`` with ``library`` prepended to ``LD_PRELOAD``; None when the
        library is absent, already preloaded, or the user opted out (``OPT_OUT=1``).
    """
    preload = environ.get("LD_PRELOAD", "")
    if library is None or environ.get(OPT_OUT, "") == "1" or "tcmalloc" in preload:
        return None
    env = dict(environ)
    env["LD_PRELOAD"] = f"{library}:{preload}" if preload else library
    return env


def reexec_with_tcmalloc(argv: Sequence[str]) -> None:
    """Replace this process by the ``thrombojax argv`` command under tcmalloc, when due.

    Returns (doing nothing) when :func:`preload_environment` says no, off Linux, or when the
    exec fails; on success it does not return.
    """
    # the same thrombojax as this process, whatever the working directory holds
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    # argv[0] as the user ran it (not "-c"): results record the command they ran
    code = f"import sys; sys.argv[0] = {sys.argv[0]!r}; sys.path.insert(0, {root!r}); " \
           "from thrombojax.cli import main; sys.exit(main())"
    _exec_under_tcmalloc([sys.executable, "-c", code, *argv])


def reexec_script_with_tcmalloc(script: str, argv: Sequence[str]) -> None:
    """Replace this process by ``python script argv`` under tcmalloc, when due.

    For the long experiment scripts run as ``python experiments/<name>.py`` (not through the
    ``thrombojax`` command): call it first in their ``__main__`` block. The same rules and
    opt-out as :func:`reexec_with_tcmalloc`.
    """
    _exec_under_tcmalloc([sys.executable, script, *argv])


def _exec_under_tcmalloc(args: list[str]) -> None:
    if not sys.platform.startswith("linux"):
        return
    env = preload_environment(os.environ, find_tcmalloc())
    if env is None:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.execve(args[0], args, env)
    except OSError:
        return
