"""The vessel-following prior alone (no model), without and with the centring pull.

Rolls each named simulation out from the dataset's ``skip_frames`` with the prior of the
default recipe (every clot node's velocity turned onto the local vessel axis at its speed, axis
width 2 vessel radii) and, for each ``K:T`` asked, the centring pull of
:func:`thrombojax.graph.section.centre_pull` (strength ``K``, tolerance ``T`` vessel radii) that
``thrombojax train --centre-pull K --centre-tolerance T`` adds to the step's prior; ``K = 0`` is
the prior alone. No model, no guards; datasets larger than 4,000 nodes are rolled out on 2,048
of them (as the ClotEntry runs train and evaluate). Prints a markdown table: the final and
largest centroid error and the largest share of the clot outside the wall, as the rollout
tables count them. Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_pull/prior_pull.py DATA SIM1,SIM2 K:T,...
"""

import sys
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import centroid_error, fit_vessel_wall, fraction_outside
from thrombojax.graph.section import centre_pull
from thrombojax.graph.vessel_axis import follow_axis_offset, vessel_axis
from thrombojax.io.hdf5 import open_dataset
from thrombojax.types import clot_mask


@partial(jax.jit, static_argnums=(3, 4, 5, 6, 7))
def roll(x_prev, x0, node_type, n_steps: int, width: float, strength: float, unit: float,
         tolerance: float) -> jax.Array:
    """``[n_steps, N, 3]``: the prior's rollout (with the pull when ``strength > 0``), one
    compiled scan."""
    mask = jnp.ones(node_type.shape[0], bool)

    def body(carry, _):
        prev, cur = carry
        t = vessel_axis(cur, node_type, mask, radius=width)
        pull = None if strength == 0 else centre_pull(
            cur, node_type, mask, unit=unit, strength=strength, tolerance=tolerance, axis=t)
        nxt = cur + (cur - prev) + follow_axis_offset(prev, cur, node_type, mask, radius=width,
                                                      axis=t, pull=pull)
        return (cur, nxt), nxt

    return jax.lax.scan(body, (x_prev, x0), None, length=n_steps)[1]


def main() -> None:
    data, names = sys.argv[1], sys.argv[2].split(",")
    settings = [tuple(float(v) for v in s.split(":")) for s in sys.argv[3].split(",")]
    ds = open_dataset(data)
    r, t0 = float(vessel_radius(ds)), study.skip_frames(ds)
    print("| simulation | pull K | tolerance (r) | final centroid error (r) | "
          "largest centroid error (r) | max clot outside |")
    print("|---|---|---|---|---|---|")
    for name in names:
        sim = ds[name]
        pos, nt = np.asarray(sim.positions, np.float32), np.asarray(sim.node_type)
        wall = fit_vessel_wall(pos[0], nt, wall_cells=sim.wall_cells)
        if nt.size > 4000:
            idx = subsample_indices(0, nt, 2048)
            pos, nt = pos[:, idx], nt[idx]
        clot, true = np.asarray(clot_mask(nt)), pos[t0 + 1:]
        for k, tol in settings:
            pred = np.asarray(roll(jnp.asarray(pos[t0 - 1]), jnp.asarray(pos[t0]),
                                   jnp.asarray(nt), pos.shape[0] - t0 - 1, 2.0 * r, k, r,
                                   tol * r))
            err = centroid_error(pred, true, clot) / r
            outside = fraction_outside(wall, pred, clot).max()
            print(f"| {name} | {k:g} | {tol:g} | {err[-1]:.2f} | {err.max():.2f} | "
                  f"{outside:.1%} |", flush=True)
    print(f"\nvessel radius {r:g}; frames from {t0}; command: {' '.join(sys.argv)}")


if __name__ == "__main__":
    main()
