"""How much of a stretch along its motion, and of a swelling, a trained step keeps.

Teacher-forced on the true frames of the rollout phase (from the dataset's ``skip_frames`` to
the last frame but one), at every frame: the clot of s_t and of the frames before it stretched
by 2 % along its motion into s_t (``thrombojax.eval.drift.swell_carry`` with
``along_motion=True``), and swollen by 2 % about its centroid (the same without it); the share
the step's next clot keeps, 1 for constant velocity, 0.5 for the half the stretch and swell
noise teach to take back in one step. And the same for a rate (``rate=True``: s_t true, the
input motion carrying a stretch or swelling of 2 % per frame): the share of the rate the next
step keeps, 1 for constant velocity, 0 for a step that stops it. A rollout whose step keeps all
of a stretch, and adds a little each step, stretches without bound. And, from the true inputs
alone, the stretch each step adds beyond the truth's (``bias``): the least-squares slope of its
next positions' error along the motion against the nodes' offsets from the centroid along it,
in % per step (> 0: the front predicted ahead of the rear). Per run (its last checkpoint): the
mean, minimum and maximum over every frame of every given simulation. Output: JSON with the
command, versions, date and load, and a printed table.

Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_shapes/stretch/carry.py OUT.json \\
        data/bendvessel_shapes.h5 bendvessel-shapes_005,bendvessel-shapes_012 LABEL=RUN ...
"""

from __future__ import annotations

import json
import pathlib
import sys

import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "exit"))
import script_args  # noqa: E402  (the command line of ../exit/)

from thrombojax.eval.drift import swell_carry  # noqa: E402
from thrombojax.eval.single_step import batched_next, scaled_simulation  # noqa: E402
from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.hdf5 import open_dataset  # noqa: E402
from thrombojax.io.outputs import atomic_write_text  # noqa: E402
from thrombojax.study import skip_frames  # noqa: E402
from thrombojax.train.state import load_trained  # noqa: E402
from thrombojax.types import clot_mask  # noqa: E402

DELTA = 0.02
KINDS = (("stretch", True, False), ("stretch_rate", True, True), ("swell", False, False),
         ("swell_rate", False, True))


def stretch_bias(step, trained, pos, nt, frames) -> list[float]:
    """Per frame: the stretch along the motion (%) the step adds beyond the truth's."""
    mask = np.ones(len(nt), bool)
    clot = np.asarray(clot_mask(nt, mask), bool)
    nxt = np.asarray(batched_next(step, trained.params, trained.stats,
                                  jnp.asarray(np.stack([step.previous(pos, t) for t in frames])),
                                  jnp.asarray(pos[frames]), jnp.asarray(nt), jnp.asarray(mask)),
                     np.float64)
    out = []
    for i, t in enumerate(frames):
        cur = pos[t, clot].astype(np.float64)
        u = cur.mean(axis=0) - pos[t - 1, clot].mean(axis=0)
        u /= np.linalg.norm(u)
        offset = (cur - cur.mean(axis=0)) @ u
        err = (nxt[i, clot] - pos[t + 1, clot]) @ u
        out.append(100.0 * float(offset @ err / (offset @ offset)))
    return out


def carries(run: str, data: str, names: list[str]) -> dict:
    """Per simulation: the stretch and swell carry (and of their rates) at every rollout-phase
    frame."""
    trained = load_trained(run, which="last")
    step, ds = trained.step, open_dataset(data)
    out = {}
    for name in names:
        pos, nt = scaled_simulation(ds, name, trained.scaling)
        frames = np.arange(max(skip_frames(ds), step.history), pos.shape[0] - 1)
        out[name] = {
            what: swell_carry(step, trained.params, trained.stats, pos, nt, frames,
                              delta=DELTA, along_motion=along, rate=rate).tolist()
            for what, along, rate in KINDS}
        out[name]["bias"] = stretch_bias(step, trained, pos, nt, frames)
    return out


def main() -> None:
    out_path, data, names, runs = script_args.parse(__doc__)
    result = {**environment(), "delta": DELTA, "data": data, "runs": {}}
    print("run: carry of a " + " | ".join(k[0] for k in KINDS) + " | stretch bias (% per "
          "step), mean (min-max)")
    for label, run in runs.items():
        sims = carries(run, data, names)
        summary = {}
        for what in [k[0] for k in KINDS] + ["bias"]:
            values = np.concatenate([s[what] for s in sims.values()])
            summary[what] = {"mean": float(values.mean()), "min": float(values.min()),
                             "max": float(values.max())}
        result["runs"][label] = {"run": run, "summary": summary, "simulations": sims}
        print(label + ": " + " | ".join(
            f"{s['mean']:.2f} ({s['min']:.2f}-{s['max']:.2f})" for s in summary.values()),
            flush=True)
    atomic_write_text(out_path, json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
