"""Where the k-step loss of a trained run comes from: the loss of each of the K unrolled steps,
without noise, on the windows of one simulation (the training loss's own terms,
``thrombojax.train.loss.window_loss_terms``, for k = 1 .. K; step j's part is
``j L(j) - (j - 1) L(j - 1)``, since L(k) is the mean over its k steps). Also the same for the
prior alone (every parameter zeroed: output 0), and each step's share of the clot-wide term.

    python experiments/results/ladder_gpu/sixth_session/kstep_loss.py DATA SIM K OUT RUN [RUN ...]

Writes ``OUT`` (JSON: per run, per k, the mean loss and clot-wide terms over the windows, from
the dataset's ``skip_frames`` on, every ``STRIDE``-th window) with the environment.
"""
import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.train.loss import window_loss_terms
from thrombojax.train.state import load_trained

STRIDE = 8
data, sim, kmax, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), pathlib.Path(sys.argv[4])
ds = open_dataset(data)
skip = study.skip_frames(ds)
report = {"command": " ".join(sys.argv), "environment": environment(), "sim": sim,
          "stride": STRIDE, "runs": {}}
for run in sys.argv[5:]:
    trained = load_trained(run, which="last")
    step = trained.step
    full, full_nt = scaled_simulation(ds, sim, trained.scaling)
    idx = subsample_indices(0, full_nt, 2048)
    pos, nt = jnp.asarray(full[:, idx]), jnp.asarray(full_nt[idx])
    mask = jnp.ones(len(idx), bool)
    starts = np.arange(max(skip, step.history), pos.shape[0] - kmax - 1, STRIDE)
    zero = jax.tree_util.tree_map(jnp.zeros_like, trained.params)
    rows = {}
    for label, params in (("model", trained.params), ("zero_output", zero)):
        # every parameter zeroed: the decoder outputs 0, so the step applies its prior plus
        # the statistics' mean acceleration
        per_k = []
        for k in range(1, kmax + 1):
            fn = jax.jit(lambda f, k=k, p=params, st=step, ts=trained.stats, n=nt, m=mask:
                         window_loss_terms(st, p, ts, f, n, m, k=k, train=False, rng=None))
            terms = [fn(pos[s - step.history:s + k + 1]) for s in starts]
            count = float(np.sum([t["count"] for t in terms]))
            per_k.append({"k": k,
                          "loss": float(np.sum([t["loss_sum"] for t in terms])) / count,
                          "clot_mean": float(np.sum([t["clot_mean_sum"] for t in terms])) / count})
            print(run, label, per_k[-1], flush=True)
        for j, row in enumerate(per_k, start=1):  # step j's own part
            prev = per_k[j - 2] if j > 1 else {"loss": 0.0, "clot_mean": 0.0}
            row["step_loss"] = j * row["loss"] - (j - 1) * prev["loss"]
            row["step_clot_mean"] = j * row["clot_mean"] - (j - 1) * prev["clot_mean"]
        rows[label] = per_k
    report["runs"][str(run)] = rows
atomic_write_text(out, json.dumps(report, indent=1))
