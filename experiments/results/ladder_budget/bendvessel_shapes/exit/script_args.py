"""The command line shared by ``exit_teacher.py`` and ``stretch.py`` in this folder:
``OUT.json DATA NAME1,NAME2,... LABEL=RUN ...``."""

from __future__ import annotations

import pathlib
import sys


def parse(doc: str) -> tuple[pathlib.Path, str, list[str], dict[str, str]]:
    """``(out_path, data, names, {label: run})`` from ``sys.argv``; exits with ``doc`` when
    arguments are missing, and refuses an ``out_path`` that exists (never replaced)."""
    if len(sys.argv) < 5:
        sys.exit(doc)
    out_path, data, names = pathlib.Path(sys.argv[1]), sys.argv[2], sys.argv[3].split(",")
    if out_path.exists():
        sys.exit(f"{out_path}: exists; not replaced")
    return out_path, data, names, dict(a.split("=", 1) for a in sys.argv[4:])
