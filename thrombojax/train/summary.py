"""The lines ``thrombojax train`` prints at the end: best validation MSE, epochs, time, files."""

from __future__ import annotations

import json
import pathlib

from thrombojax.train.plots import best_epoch
from thrombojax.train.state import read_run_config

__all__ = ["run_summary"]


def run_summary(run_dir: str | pathlib.Path, model_name: str) -> str:
    """Summarise a finished run from its ``metrics.jsonl``.

    Returns:
        Lines naming the model, epochs done, the best checkpoint's score (validation rollout
        MSE with its ratio to constant velocity, else validation MSE, else training MSE without
        a validation split) and its epoch, elapsed training time and where the files are.
    """
    run_dir = pathlib.Path(run_dir)
    records = []
    log = run_dir / "metrics.jsonl"
    if log.is_file():
        records = [json.loads(ln) for ln in log.read_text().splitlines() if ln.strip()]
    epochs = [r for r in records if "epoch" in r and "train_mse" in r]
    lines = [f"trained {model_name}: {len(epochs)} epoch(s)"]
    if epochs:
        lines[0] += f", {epochs[-1].get('time_s', 0.0):.1f} s"
    select_by = _select_by(run_dir)
    found = best_epoch(epochs, select_by)
    if found is not None:
        epoch, value, key = found
        label = {"val_rollout_mse": "validation rollout", "val_mse": "validation"}.get(
            key, "training (no validation split)")
        lines.append(f"best checkpoint: the last epoch ({epoch}, --select-by last), {label} "
                     f"MSE {value:.4g}" if select_by == "last" else
                     f"best {label} MSE {value:.4g} at epoch {epoch}")
        best = next(r for r in epochs if r["epoch"] == epoch)
        if key == "val_rollout_mse":  # in plain words, beside constant velocity
            ratio = best["val_rollout_cv_ratio"]
            lines.append(
                f"its validation rollout (model alone): {ratio:.3g}x the constant-velocity "
                f"MSE ({'better' if ratio < 1 else 'worse'} than extrapolating the velocity), "
                f"final clot centroid {best['val_rollout_centroid_r']:.3g} vessel radii from "
                "the truth")
    lines.append(f"files: {run_dir}/config.json, {run_dir}/checkpoints/{{best,last}}, "
                 f"{run_dir}/metrics.jsonl, {run_dir}/loss.png")
    return "\n".join(lines)


def _select_by(run_dir: pathlib.Path) -> str:
    """The run's ``select_by`` (:func:`~thrombojax.train.state.read_run_config`); ``"mse"`` for
    runs saved before the option existed."""
    return str(read_run_config(run_dir)["train"].get("select_by", "mse"))
