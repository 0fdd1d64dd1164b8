"""The vessel-following prior alone (no model) on BendVessel: does it carry the clot into the wall?

Rolls each named simulation out from its ``skip_frames`` with the prior of the default recipes
(``follow_axis``: every clot node's velocity turned onto the local vessel axis at its speed,
:func:`thrombojax.graph.vessel_axis.axis_speed_velocity`, axis width 2 vessel radii), no model
and no guards, two ways:

- ``tangent at s_t``: the axis at the current positions, as the learned step's prior;
- ``Heun``: the axis averaged over the current positions and the ones the first turn reaches
  (signs aligned, normalised), then the velocity turned onto that: a second-order step along a
  curved axis.

Prints a markdown table: the clot centroid's distance to the nearest vessel node every 4
frames (about 1 r when the clot is centred in a tube of radius 1 r), its final error and the
largest share of the clot outside (as the rollout tables count it), beside the true clot's.
Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_hold/prior_drift.py DATA SIM1,SIM2,...
"""

import sys

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import centroid_error, fit_vessel_wall, fraction_outside
from thrombojax.graph.vessel_axis import axis_speed_velocity, vessel_axis
from thrombojax.io.hdf5 import open_dataset
from thrombojax.types import NodeType

RULES = ("tangent at s_t", "Heun")


def roll(positions, node_type, rule: str, t0: int, radius: float) -> np.ndarray:
    """Frames t0 + 1 .. end of the prior-alone rollout under ``rule``."""
    clot = jnp.asarray(node_type != NodeType.VESSEL)[:, None]
    mask = jnp.ones(node_type.size, bool)
    axis = jax.jit(lambda x: vessel_axis(x, jnp.asarray(node_type), mask, radius=radius))
    frames = [jnp.asarray(positions[t0 - 1]), jnp.asarray(positions[t0])]
    for _ in range(positions.shape[0] - t0 - 1):
        x_prev, x_cur = frames[-2], frames[-1]
        v = x_cur - x_prev
        t = axis(x_cur)
        step = axis_speed_velocity(v, t)
        if rule == "Heun":
            t2 = axis(jnp.where(clot, x_cur + step, x_cur))
            t2 = jnp.where(jnp.sum(t * t2, -1, keepdims=True) < 0, -t2, t2)
            tm = (t + t2) / jnp.maximum(jnp.linalg.norm(t + t2, axis=-1, keepdims=True), 1e-12)
            step = axis_speed_velocity(step, tm)
        frames.append(jnp.where(clot, x_cur + step, x_cur))
    return np.asarray(jnp.stack(frames[2:]))


def centred(frames: np.ndarray, clot: np.ndarray, tree: cKDTree, r: float) -> str:
    """The clot centroid's distance to the nearest vessel node every 4 frames, in r."""
    c = frames[:, clot].mean(axis=1)[::4]
    return " ".join(f"{tree.query(x)[0] / r:.2f}" for x in c)


def main() -> None:
    data, names = sys.argv[1], sys.argv[2].split(",")
    ds = open_dataset(data)
    r = float(vessel_radius(ds))
    t0 = study.skip_frames(ds)
    print("| simulation | rollout | centroid to the nearest vessel node every 4 frames (r) | "
          "final centroid error (r) | max clot outside |")
    print("|---|---|---|---|---|")
    for name in names:
        sim = ds[name]
        pos = np.asarray(sim.positions, np.float32)
        nt = np.asarray(sim.node_type)
        clot = nt != NodeType.VESSEL
        wall = fit_vessel_wall(pos[0], nt, wall_cells=sim.wall_cells)
        tree = cKDTree(pos[0, ~clot])
        true = pos[t0 + 1:]

        for rule in RULES:
            pred = roll(pos, nt, rule, t0, 2.0 * r)
            final = centroid_error(pred, true, clot)[-1] / r
            outside = fraction_outside(wall, pred, clot).max()
            print(f"| {name} | {rule} | {centred(pred, clot, tree, r)} | {final:.2f} | "
                  f"{outside:.1%} |")
        outside = fraction_outside(wall, true, clot).max()
        print(f"| {name} | truth | {centred(true, clot, tree, r)} | - | {outside:.1%} |")
    print(f"\nvessel radius {r:g}; frames from {t0}; command: {' '.join(sys.argv)}")


if __name__ == "__main__":
    main()
