"""How much of the next frame the past frames alone predict: extrapolation baselines in one step.

    python experiments/extrapolation.py --dataset data/bendvessel.h5 \
        --out experiments/results/extrapolation

For every simulation, over the windows of the rollout phase (current frame t >= the dataset's
``skip_frames``, t >= 2), the clot nodes' one-step MSE of three predictions of s_{t+1} that use no
model, beside constant velocity (CV, ``s_t + v_t``):

- constant acceleration (CA): ``s_t + v_t + a_{t-1}``, the last acceleration repeated;
- half acceleration: ``s_t + v_t + a_{t-1} / 2``;
- zero velocity: ``s_t`` (the clot stops).

A ratio to CV below 1 says the acceleration before t carries information the current velocity
does not, which a learned step that reads one velocity cannot use (``make_step(..., history=2)``
reads it, :mod:`thrombojax.simulator.step`). Errors in vessel radii squared (r^2). Writes
``table.md`` and ``extrapolation.json`` with the command, device, versions and date.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.types import clot_mask

PREDICTIONS = ("constant velocity", "constant acceleration", "half acceleration",
               "zero velocity")


def one_step_errors(positions: np.ndarray, clot: np.ndarray, skip: int) -> dict[str, float]:
    """Mean one-step MSE over the clot nodes of the windows ``t >= max(skip, 2)`` of one
    simulation ``positions [T, N, 3]``, per prediction of :data:`PREDICTIONS` (units of
    ``positions`` squared)."""
    x = positions[:, clot].astype(np.float64)
    t = np.arange(max(skip, 2), x.shape[0] - 1)
    if t.size == 0:
        raise ValueError(f"no window t >= {max(skip, 2)} in {x.shape[0]} frames")
    v = x[t] - x[t - 1]
    a_prev = x[t] - 2 * x[t - 1] + x[t - 2]
    truth = x[t + 1]
    guesses = {"constant velocity": x[t] + v, "constant acceleration": x[t] + v + a_prev,
               "half acceleration": x[t] + v + 0.5 * a_prev, "zero velocity": x[t]}
    return {k: float(((g - truth) ** 2).mean()) for k, g in guesses.items()}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", required=True, help="HDF5 dataset")
    parser.add_argument("--out", required=True, help="output folder (table.md, JSON)")
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    check_targets([out / "table.md", out / "extrapolation.json"], force=args.force)
    ds = open_dataset(args.dataset)
    skip = study.skip_frames(ds)
    r = vessel_radius(ds)
    per_sim = {}
    for name in ds.names:
        pos = np.asarray(ds.positions(name), np.float64)
        errs = one_step_errors(pos, clot_mask(np.asarray(ds.node_type(name))), skip)
        per_sim[name] = {k: v / r**2 for k, v in errs.items()}
    mean = {k: float(np.mean([s[k] for s in per_sim.values()])) for k in PREDICTIONS}
    rows = [[k, mean[k], mean[k] / mean["constant velocity"],
             float(np.median([s[k] / s["constant velocity"] for s in per_sim.values()])),
             float(np.max([s[k] / s["constant velocity"] for s in per_sim.values()]))]
            for k in PREDICTIONS]
    table = markdown_table(["prediction of s_{t+1}", "1-step MSE (r^2)", "/ CV (pooled)",
                            "/ CV (median sim)", "/ CV (worst sim)"], rows)
    env = environment()
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "table.md", (
        f"# One-step extrapolation baselines ({pathlib.Path(args.dataset).name}, "
        f"{len(per_sim)} simulations, rollout phase t >= {max(skip, 2)})\n\n{table}\n"
        "Clot nodes, windows of the rollout phase; one vessel radius r is "
        f"{r:.4g} in the dataset's units ('{ds.attrs.get('units', '?')}').\n\n"
        + "".join(f"- {k}: {v}\n" for k, v in env.items())))
    atomic_write_text(out / "extrapolation.json", json.dumps(
        {"environment": env, "skip_frames": skip, "radius": r, "mean": mean,
         "simulations": per_sim}, indent=1))
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
