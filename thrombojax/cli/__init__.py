"""The ``thrombojax`` command. Thin: every subcommand parses flags and calls one library function.

Errors that thrombojax raises on purpose (:class:`thrombojax.errors.ThrombojaxError`) and
missing files are printed as one line and exit with status 2, never as a traceback. The
subcommands live in :mod:`.data_commands` (info, import, generate, export),
:mod:`.train_commands` (train), :mod:`.run_commands` (evaluate, rollout),
:mod:`.bench_commands` (bench),
:mod:`.ensemble_commands` (ensemble) and :mod:`.experiment_commands` (experiment list / run);
library imports happen inside each command so ``thrombojax --help`` stays fast.
:mod:`.allocator` runs the command under tcmalloc.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Sequence

from thrombojax.cli import (
    allocator,
    bench_commands,
    data_commands,
    ensemble_commands,
    experiment_commands,
    run_commands,
    train_commands,
)
from thrombojax.errors import ThrombojaxError

__all__ = ["main", "build_parser"]

_REGISTRARS = [*data_commands.REGISTRARS, *train_commands.REGISTRARS, *run_commands.REGISTRARS,
               *bench_commands.REGISTRARS, *ensemble_commands.REGISTRARS,
               *experiment_commands.REGISTRARS]


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``thrombojax generate: error: argument --sims: ...``."""

    def error(self, message: str):
        print(f"{self.prog}: error: {' '.join(message.split())} (see '{self.prog} --help')",
              file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every working subcommand."""
    parser = _Parser(
        prog="thrombojax",
        description=(
            "Learned step-by-step surrogates of mechanical-thrombectomy simulations: "
            "generate or import datasets, train MeshGraphNet / Transolver / Erwin, "
            "roll them out and benchmark them."
        ),
    )
    from thrombojax import __version__

    parser.add_argument("--version", action="version", version=f"thrombojax {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for register in _REGISTRARS:
        register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``thrombojax`` console script. Returns the exit status.

    Run from the command line (``argv`` None) it first re-executes itself once under tcmalloc
    when that is installed (:mod:`thrombojax.cli.allocator`; opt out: THROMBOJAX_NO_TCMALLOC=1).
    """
    args = build_parser().parse_args(argv)
    if argv is None:
        allocator.reexec_with_tcmalloc(sys.argv[1:])
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning(args.command)
            result = args.func(args)
        sys.stdout.flush()
    except BrokenPipeError:  # `thrombojax info X | head`: the reader has gone, nothing to say
        _silence_stdout()
        return 0
    except (ThrombojaxError, OSError) as err:  # OSError: missing, unreadable, read-only paths
        text = " ".join(str(err).split())
        print(f"thrombojax {args.command}: error: {text}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"thrombojax {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(result or 0)


def _one_line_warning(command: str):
    """Print warnings as ``thrombojax COMMAND: warning: ...`` (one line, no source excerpt)."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"thrombojax {command}: warning: {' '.join(str(message).split())}",
              file=sys.stderr)
    return show


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush raises no second error."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


if __name__ == "__main__":
    sys.exit(main())
