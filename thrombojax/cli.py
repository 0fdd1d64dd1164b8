"""The ``thrombojax`` command. Thin: every subcommand parses flags and calls one library function.

Errors that thrombojax raises on purpose (:class:`thrombojax.errors.ThrombojaxError`) and
missing files are printed as one line and exit with status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

from thrombojax.errors import ThrombojaxError

__all__ = ["main", "build_parser"]

_Registrar = Callable[["argparse._SubParsersAction"], None]

# ---- subcommands: each `_add_<name>` registers one parser and sets `func` ------------------

_REGISTRARS: list[_Registrar] = []


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every working subcommand."""
    parser = argparse.ArgumentParser(
        prog="thrombojax",
        description=(
            "Learned step-by-step surrogates of mechanical-thrombectomy simulations: "
            "generate or import datasets, train MeshGraphNet / Transolver / Erwin, "
            "roll them out and benchmark them."
        ),
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for register in _REGISTRARS:
        register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``thrombojax`` console script. Returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        result = args.func(args)
    except (ThrombojaxError, FileNotFoundError, FileExistsError, IsADirectoryError) as err:
        print(f"thrombojax {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"thrombojax {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(result or 0)


if __name__ == "__main__":
    sys.exit(main())
