"""Does a model know the clot's exit when it is given the true frames? Teacher-forced clot-wide
acceleration along the clot's motion, before and during the exit, against the truth.

Every rollout of the shapes-trained models lags the true clot over its last 4-7 frames, where the
true clot speeds up from its steady slide (0.28-0.45 r per frame) to 0.67-1.17 r per frame as it
passes the outlet's flare (``exit_split.py``, in this folder). This script asks whether the
one step already misses that acceleration from the true inputs, or only the rollout: for every
window ``t`` of the rollout phase it runs the step on the true ``s_{t-H} .. s_t`` and compares
the predicted clot centroid's acceleration along the motion (``c_{t+1} - 2 c_t + c_{t-1}`` on
``(c_t - c_{t-1}) / |.|``) with the true one, in vessel radii per frame squared. The exit
windows are those whose true next speed exceeds 1.15x the simulation's median rollout-phase
speed (the rule of ``exit_split.py``). A step that reads the acceleration before t
(``history`` 2) is also run with that acceleration taken out of its inputs (``s_{t-2}`` replaced by
``2 s_{t-1} - s_t``, so ``a_{t-1} = 0``): what it predicts from the geometry and the velocity
alone, as in a rollout whose clot has not yet started to speed up. Output: one JSON row per
run (command, versions, date, load) and a printed table.

Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_shapes/exit/exit_teacher.py OUT.json \\
        data/bendvessel_shapes.h5 bendvessel-shapes_005,bendvessel-shapes_012 LABEL=RUN ...
"""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import script_args

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.single_step import batched_next, scaled_simulation
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.study import skip_frames
from thrombojax.train.state import load_trained
from thrombojax.types import clot_mask

EXIT_SPEEDUP = 1.15


def _centroids(trained, prev, cur, node_type, clot):
    """Teacher-forced next clot centroids ``[B, 3]`` of the windows ``(prev [B, ...], cur)``."""
    mask = jnp.ones(len(node_type), bool)
    nxt = np.asarray(batched_next(trained.step, trained.params, trained.stats, jnp.asarray(prev),
                                  jnp.asarray(cur), jnp.asarray(node_type), mask))
    return nxt[:, clot].astype(np.float64).mean(axis=1)


def along_accelerations(run: str, data: str, names: list[str]) -> dict:
    """Per simulation: the rollout-phase windows' true and predicted clot-wide acceleration
    along the motion (vessel radii per frame^2) and which windows are exit windows."""
    trained = load_trained(run, which="last")
    step, ds = trained.step, open_dataset(data)
    r = vessel_radius(ds) / float(trained.scaling.scale)
    skip = max(skip_frames(ds), step.history)
    out = {}
    for name in names:
        pos, nt = scaled_simulation(ds, name, trained.scaling)
        mask = np.ones(len(nt), bool)
        clot = np.asarray(clot_mask(nt, mask), bool)
        frames = np.arange(skip, pos.shape[0] - 1)
        prev = np.stack([np.asarray(step.previous(pos, t), np.float32) for t in frames])
        c = pos[:, clot].astype(np.float64).mean(axis=1)
        c_pred = _centroids(trained, prev, pos[frames], nt, clot)
        if step.history == 2:  # a_{t-1} = 0: s_{t-2} := 2 s_{t-1} - s_t
            flat = prev.copy()
            flat[:, -2] = 2 * prev[:, -1] - pos[frames]  # (after a rest frame if any)
            c_flat = _centroids(trained, flat, pos[frames], nt, clot)
        v = c[frames] - c[frames - 1]
        along = v / np.linalg.norm(v, axis=1, keepdims=True)
        a_true = np.einsum("tk,tk->t", c[frames + 1] - 2 * c[frames] + c[frames - 1], along)
        a_pred = np.einsum("tk,tk->t", c_pred - 2 * c[frames] + c[frames - 1], along)
        speed_next = np.linalg.norm(c[frames + 1] - c[frames], axis=1)
        exit_ = speed_next > EXIT_SPEEDUP * np.median(speed_next)
        out[name] = {"frames": frames.tolist(), "exit": exit_.tolist(),
                     "a_true_r": (a_true / r).tolist(), "a_pred_r": (a_pred / r).tolist()}
        if step.history == 2:
            a_flat = np.einsum("tk,tk->t", c_flat - 2 * c[frames] + c[frames - 1], along)
            out[name]["a_pred_no_history_r"] = (a_flat / r).tolist()
    return out


def summary(sims: dict) -> dict:
    """Means over simulations: steady and exit windows' mean acceleration (true, predicted),
    and the sum over the exit windows (the speed gained in the exit, r per frame)."""
    rows: dict[str, list] = {}
    for s in sims.values():
        ex = np.asarray(s["exit"])
        onset = int(np.argmax(ex))  # the first exit window
        for key, what in (("true", "a_true_r"), ("pred", "a_pred_r"),
                          ("pred_no_history", "a_pred_no_history_r")):
            if what not in s:
                continue
            a = np.asarray(s[what])
            rows.setdefault(f"steady_{key}", []).append(a[~ex].mean())
            rows.setdefault(f"exit_gain_{key}", []).append(a[ex].sum())
            rows.setdefault(f"onset_{key}", []).append(a[onset - 1:onset + 2].mean())
    return {k: float(np.mean(v)) for k, v in rows.items()}


def main() -> None:
    out_path, data, names, runs = script_args.parse(__doc__)
    result = {**environment(), "data": data, "runs": {}}
    print(f"{'model':24s} steady a: true / pred | exit speed gain: true / pred / no history"
          " | onset a: true / pred / no history")
    for label, run in runs.items():
        sims = along_accelerations(run, data, names)
        s = summary(sims)
        result["runs"][label] = {"run": run, "summary": s, "simulations": sims}
        nh = (f"{s['exit_gain_pred_no_history']:.3f}", f"{s['onset_pred_no_history']:.4f}") \
            if "exit_gain_pred_no_history" in s else ("-", "-")
        print(f"{label:24s} {s['steady_true']:+.4f} / {s['steady_pred']:+.4f} | "
              f"{s['exit_gain_true']:.3f} / {s['exit_gain_pred']:.3f} / {nh[0]} | "
              f"{s['onset_true']:.4f} / {s['onset_pred']:.4f} / {nh[1]}")
    atomic_write_text(out_path, json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
