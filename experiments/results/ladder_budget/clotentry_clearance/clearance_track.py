"""The clearance a guarded rollout reads against the true clot's, step by step.

Rolls each run out guarded (the ladder's default guards, ``--nodes`` nodes per simulation, as
``bendvessel_shapes/cross_eval.py`` does) on the chosen simulations and records, at every step,
the clot's clearance (``thrombojax.graph.clearance.clot_clearance``: the distance from the clot's
centroid to the nearest vessel node, in vessel radii) of the rollout and of the true clot, and
the centroid's speed of each. Writes ``OUT.json`` (every step) and ``OUT.md`` (a table by
windows of 20 steps). Run from the repository root::

    python experiments/results/ladder_budget/clotentry_clearance/clearance_track.py \\
        --nodes 2048 OUT data/clotentry.h5 clotentry_008,clotentry_009 LABEL=RUN ...
"""

import argparse
import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, "experiments")

from thrombojax import study  # noqa: E402
from thrombojax.data.augment import subsample_indices  # noqa: E402
from thrombojax.data.radius import vessel_radius  # noqa: E402
from thrombojax.eval.drift import centroid_speed  # noqa: E402
from thrombojax.eval.single_step import scaled_simulation  # noqa: E402
from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.graph.clearance import clot_clearance  # noqa: E402
from thrombojax.io.hdf5 import open_dataset  # noqa: E402
from thrombojax.io.outputs import atomic_write_text  # noqa: E402
from thrombojax.simulator.guard_set import build_guards  # noqa: E402
from thrombojax.simulator.rollout import rollout_with_corrections  # noqa: E402
from thrombojax.train.state import load_trained  # noqa: E402
from thrombojax.types import clot_mask  # noqa: E402


def track(run: pathlib.Path, ds, name: str, n_nodes: int) -> dict:
    """Per step: clearance (r) and centroid speed (r per frame), rollout and truth."""
    trained = load_trained(run, which="last")
    step = trained.step
    skip = max(study.skip_frames(ds), 1)
    r = vessel_radius(ds) / float(trained.scaling.scale)
    full, full_nt = scaled_simulation(ds, name, trained.scaling)
    idx = subsample_indices(0, full_nt, n_nodes)
    pos, nt = full[:, idx], full_nt[idx]
    n = pos.shape[0] - 1 - skip
    mask = np.ones(len(nt), bool)
    guards = build_guards(full[0], full_nt, pos[skip], nt, radius=r,
                          wall_cells=ds[name].wall_cells)
    pred, _ = rollout_with_corrections(step, trained.params, trained.stats,
                                       step.previous(pos, skip), pos[skip], nt, mask, n,
                                       guards=guards)
    pred = np.concatenate([pos[skip:skip + 1], np.asarray(pred)])
    true = pos[skip:]
    clot = clot_mask(nt)

    def clearance(frames):  # one compiled call over every frame
        per_frame = jax.jit(jax.vmap(lambda f: clot_clearance(f, nt, mask, scale=r)))
        return np.asarray(per_frame(jnp.asarray(frames)))[:, clot][:, 0, 0].tolist()

    def speed(frames):
        return (centroid_speed(frames, clot) / r).tolist()

    return {"clearance_r": clearance(pred), "clearance_true_r": clearance(true),
            "speed_r": speed(pred), "speed_true_r": speed(true)}


def table(results: dict) -> str:
    lines = ["| row | simulation | steps | clearance (r), rollout / truth | speed (r per frame), "
             "rollout / truth |", "|---|---|---|---|---|"]
    for label, sims in results.items():
        for name, t in sims.items():
            c, ct = np.array(t["clearance_r"]), np.array(t["clearance_true_r"])
            s, st = np.array(t["speed_r"]), np.array(t["speed_true_r"])
            for a in range(0, len(s), 20):
                lines.append(f"| {label} | {name} | {a}-{min(a + 20, len(s))} | "
                             f"{c[a:a + 20].mean():.2f} / {ct[a:a + 20].mean():.2f} | "
                             f"{s[a:a + 20].mean():.3f} / {st[a:a + 20].mean():.3f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--nodes", type=int, default=2048)
    p.add_argument("out", type=pathlib.Path, help="output stem (OUT.json, OUT.md)")
    p.add_argument("data")
    p.add_argument("names", help="simulations, comma-separated")
    p.add_argument("rows", nargs="+", help="LABEL=RUN")
    a = p.parse_args()
    ds = open_dataset(a.data)
    results = {}
    for spec in a.rows:
        label, _, run = spec.partition("=")
        results[label] = {}
        for name in a.names.split(","):
            print("rolling out", label, name, flush=True)
            results[label][name] = track(pathlib.Path(run), ds, name, a.nodes)
    env = environment()
    out = {"measured": env, "rows": results}
    atomic_write_text(a.out.with_suffix(".json"), json.dumps(out, indent=1) + "\n")
    atomic_write_text(a.out.with_suffix(".md"), table(results) + "\n" + "\n".join(
        f"- {k}: {v}" for k, v in env.items()) + "\n")
    print("wrote", a.out.with_suffix(".md"))


if __name__ == "__main__":
    main()
