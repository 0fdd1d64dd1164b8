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

import pathlib
import sys
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import centroid_error, fit_vessel_wall, fraction_outside
from thrombojax.graph.clearance import clot_clearance
from thrombojax.graph.vessel_axis import axis_speed_velocity, vessel_axis
from thrombojax.io.hdf5 import open_dataset
from thrombojax.types import clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3]))  # experiments/
from follow_axis import roll as follow_roll  # noqa: E402

RULES = ("tangent at s_t", "Heun")


@partial(jax.jit, static_argnums=(3, 4))
def heun_roll(x_prev, x0, node_type, n_steps: int, radius: float) -> jax.Array:
    """``[n_steps, N, 3]``: the prior's rollout with the axis averaged over ``s_t`` and the
    end of the first turn (signs aligned, normalised), one compiled scan."""
    mask = jnp.ones(node_type.shape[0], bool)
    clot = clot_mask(node_type, mask)[:, None]

    def body(carry, _):
        prev, cur = carry
        t = vessel_axis(cur, node_type, mask, radius=radius)
        step = axis_speed_velocity(cur - prev, t)
        t2 = vessel_axis(jnp.where(clot, cur + step, cur), node_type, mask, radius=radius)
        t2 = jnp.where(jnp.sum(t * t2, -1, keepdims=True) < 0, -t2, t2)
        tm = (t + t2) / jnp.maximum(jnp.linalg.norm(t + t2, axis=-1, keepdims=True), 1e-12)
        nxt = jnp.where(clot, cur + axis_speed_velocity(step, tm), cur)
        return (cur, nxt), nxt

    return jax.lax.scan(body, (x_prev, x0), None, length=n_steps)[1]


# the learned step's prior: every clot node turned onto its axis at s_t, at its speed
_follow = jax.jit(partial(follow_roll, "axis speed, per node"), static_argnums=(3, 4))


def roll(positions, node_type, rule: str, t0: int, radius: float) -> np.ndarray:
    """Frames t0 + 1 .. end of the prior-alone rollout under ``rule``."""
    args = (jnp.asarray(positions[t0 - 1]), jnp.asarray(positions[t0]),
            jnp.asarray(node_type), positions.shape[0] - t0 - 1, radius)
    return np.asarray(heun_roll(*args) if rule == "Heun" else _follow(*args))


def centred(frames: np.ndarray, node_type: np.ndarray, r: float) -> str:
    """The clot centroid's distance to the nearest vessel node every 4 frames, in r
    (:func:`thrombojax.graph.clearance.clot_clearance`)."""
    mask = jnp.ones(node_type.size, bool)
    nt = jnp.asarray(node_type)
    clearance = jax.vmap(lambda x: clot_clearance(x, nt, mask, scale=r).max())(
        jnp.asarray(frames[::4]))
    return " ".join(f"{c:.2f}" for c in np.asarray(clearance))


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
        clot = np.asarray(clot_mask(nt))
        wall = fit_vessel_wall(pos[0], nt, wall_cells=sim.wall_cells)
        true = pos[t0 + 1:]

        for rule in RULES:
            pred = roll(pos, nt, rule, t0, 2.0 * r)
            final = centroid_error(pred, true, clot)[-1] / r
            outside = fraction_outside(wall, pred, clot).max()
            print(f"| {name} | {rule} | {centred(pred, nt, r)} | {final:.2f} | "
                  f"{outside:.1%} |")
        outside = fraction_outside(wall, true, clot).max()
        print(f"| {name} | truth | {centred(true, nt, r)} | - | {outside:.1%} |")
    print(f"\nvessel radius {r:g}; frames from {t0}; command: {' '.join(sys.argv)}")


if __name__ == "__main__":
    main()
