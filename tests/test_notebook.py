"""The quickstart notebook runs end to end (tiny config) and leaves its plots behind."""

from __future__ import annotations

import pathlib
import shutil

import nbformat
from nbclient import NotebookClient

NOTEBOOK = pathlib.Path(__file__).resolve().parent.parent / "notebooks" / "quickstart.ipynb"


def test_quickstart_notebook_executes(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    shutil.copy(NOTEBOOK, tmp_path / NOTEBOOK.name)
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    out = tmp_path / "quickstart_output"
    assert (out / "rollout_metrics.png").stat().st_size > 10_000
    assert (out / "rollout.gif").is_file() and (out / "run" / "config.json").is_file()
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert images, "the plot cell displayed no image"
