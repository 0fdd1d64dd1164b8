"""The quickstart notebook runs end to end (tiny config), twice, and leaves its plots behind."""

from __future__ import annotations

import os
import pathlib
import shutil

import nbformat
import pytest
from nbclient import NotebookClient

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)

NOTEBOOK = pathlib.Path(__file__).resolve().parent.parent / "notebooks" / "quickstart.ipynb"


def test_quickstart_notebook_executes(tmp_path, monkeypatch):
    # the kernel imports this checkout's thrombojax, not whichever copy is installed
    repo = str(NOTEBOOK.parent.parent)
    paths = [repo, os.environ.get("PYTHONPATH")]
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in paths if p))
    shutil.copy(NOTEBOOK, tmp_path / NOTEBOOK.name)
    for _ in range(2):  # a second "Run All" in the same folder works too
        nb = nbformat.read(NOTEBOOK, as_version=4)
        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": str(tmp_path)}}).execute()
    out = tmp_path / "quickstart_output"
    assert (out / "rollout_metrics.png").stat().st_size > 10_000
    assert (out / "rollout.gif").is_file() and (out / "run" / "config.json").is_file()
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert images, "the plot cell displayed no image"
