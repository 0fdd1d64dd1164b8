"""The lines ``thrombojax train`` prints at the end: best validation MSE, epochs, time, files."""

from __future__ import annotations

import json
import pathlib

__all__ = ["run_summary"]


def run_summary(run_dir: str | pathlib.Path, model_name: str) -> str:
    """Summarise a finished run from its ``metrics.jsonl``.

    Returns:
        Lines naming the model, epochs done, best validation MSE (training MSE without a
        validation split) and its epoch, elapsed training time and where the files are.
    """
    run_dir = pathlib.Path(run_dir)
    records = []
    log = run_dir / "metrics.jsonl"
    if log.is_file():
        records = [json.loads(ln) for ln in log.read_text().splitlines() if ln.strip()]
    epochs = [r for r in records if "epoch" in r and "train_mse" in r]
    key = "val_mse" if any("val_mse" in r for r in epochs) else "train_mse"
    lines = [f"trained {model_name}: {len(epochs)} epoch(s)"]
    if epochs:
        best = min(epochs, key=lambda r: r.get(key, float("inf")))
        label = "validation" if key == "val_mse" else "training (no validation split)"
        lines[0] += f", {epochs[-1].get('time_s', 0.0):.1f} s"
        lines.append(f"best {label} MSE {best[key]:.4g} at epoch {best['epoch']}")
    lines.append(f"files: {run_dir}/config.json, {run_dir}/checkpoints/{{best,last}}, "
                 f"{run_dir}/metrics.jsonl, {run_dir}/loss.png")
    return "\n".join(lines)
