"""TensorBoard event files beside a run's ``metrics.jsonl`` (tensorboardX, an optional extra).

:func:`tensorboard_logger` returns a training callback (``train(..., callback=...)``) that writes
the loss and MSE of every step and, whenever the training loop appends an epoch record to
``metrics.jsonl``, every number of that record (validation MSE, learning rate, time), into
``RUN/tensorboard/``. Without tensorboardX (``pip install 'thrombojax[experiments]'``) it returns
``None`` and a note saying so; runs and results are the same either way.
"""

from __future__ import annotations

import json
import pathlib
import shutil
from collections.abc import Callable

__all__ = ["tensorboard_logger", "TENSORBOARD_NOTE"]

TENSORBOARD_NOTE = ("tensorboardX is not installed: no TensorBoard event files were written "
                    "(pip install 'thrombojax[experiments]')")


def tensorboard_logger(run_dir: str | pathlib.Path, *, resume: bool = False
                       ) -> tuple[Callable[[int, dict], None] | None, Callable[[], None]]:
    """``(callback, close)`` writing ``run_dir/tensorboard``; ``(None, no-op)`` without
    tensorboardX. ``resume``: the epochs already in ``metrics.jsonl`` were logged before;
    otherwise earlier event files of the folder are removed (a fresh run)."""
    try:
        from tensorboardX import SummaryWriter
    except ImportError:
        return None, lambda: None
    run_dir = pathlib.Path(run_dir)
    if not resume:
        shutil.rmtree(run_dir / "tensorboard", ignore_errors=True)
    writer = SummaryWriter(str(run_dir / "tensorboard"))
    log = run_dir / "metrics.jsonl"
    state = {"size": -1, "step": 0}

    def new_epochs() -> list[dict]:
        """Epoch records past the last one written (a resumed run continues the count)."""
        size = log.stat().st_size if log.is_file() else 0
        if size == state["size"]:
            return []
        state["size"] = size
        records = [json.loads(ln) for ln in log.read_text().splitlines() if ln.strip()]
        new = [r for r in records if "epoch" in r and "event" not in r
               and r.get("step", 0) > state["step"]]
        state["step"] = max([state["step"], *(r["step"] for r in new)])
        return new

    if resume:
        new_epochs()  # its earlier epochs are in its earlier event file

    def callback(step: int, metrics: dict) -> None:
        for key in ("loss", "mse"):
            if key in metrics:
                writer.add_scalar(f"step/{key}", metrics[key], step)
        for record in new_epochs():
            for key, value in record.items():
                if key not in ("epoch", "step") and isinstance(value, int | float):
                    writer.add_scalar(f"epoch/{key}", value, record["step"])
        writer.flush()

    return callback, writer.close
