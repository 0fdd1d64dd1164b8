"""When BendVessel's true clot passes the vessel's open end: per simulation, the share of its
nodes that the guards' wall query calls past the end (``WallQuery.past_end``, the test that
containment and ``build_guards(..., free_past_end=True)`` use), over its last frames, and the
first frame step of its exit (``../bendvessel_exit/exit_truth.exit_of``: where the true clot
speeds up). No model is run; the table is written atomically and replaced only with
``--force``. From the repository root::

    python experiments/results/ladder_budget/guards_exit/past_end.py data/bendvessel.h5 \\
        --held-out bendvessel_005,bendvessel_012,bendvessel_019 --validation bendvessel_009 \\
        --out past_end.md
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import clot_centroids
from thrombojax.simulator.wall import nearest_wall_point
from thrombojax.simulator.wall_build import wall_from_simulation
from thrombojax.types import clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bendvessel_exit"))
from exit_truth import add_split_arguments, exit_of, open_split, write_table  # noqa: E402

LAST = 8


@jax.jit
def past_end_share(frames: jax.Array, wall) -> jax.Array:
    """``[F]``: the share of each frame's points ``frames [F, C, 3]`` past the wall's open end
    (one compiled program per wall shape, all frames at once)."""
    return jax.vmap(lambda x: jnp.mean(nearest_wall_point(x, wall).past_end))(frames)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)
    args = ap.parse_args()
    ds, held, validation = open_split(args)
    radius = float(vessel_radius(ds))
    heads = " | ".join(f"t-{k}" if k else "t (last)" for k in range(LAST - 1, -1, -1))
    lines = [f"Share of the true clot's nodes past the vessel's open end over the last {LAST} "
             "frames (t: the last frame), and the exit's first frame step (the centroid's step "
             "from frame k to k + 1 is the first of the exit's fast run).", "",
             f"| simulation | exit from frame | {heads} |",
             "|---|---|" + "---|" * LAST]
    for name in held + validation:
        sim = ds[name]
        pos, node_type = np.asarray(sim.positions, np.float32), np.asarray(sim.node_type)
        clot = clot_mask(node_type)
        wall = wall_from_simulation(pos[0], node_type, sim.wall_cells)
        share = np.asarray(past_end_share(jnp.asarray(pos[-LAST:, clot]), wall))
        speed = np.linalg.norm(np.diff(clot_centroids(pos, clot), axis=0), axis=1)
        kind = "held out" if name in held else "validation"
        lines.append(f"| {name} ({kind}, {pos.shape[0]} frames) | {exit_of(speed)} | "
                     + " | ".join(f"{s:.0%}" for s in share) + " |")
    write_table(args.out, lines, radius)


if __name__ == "__main__":
    main()
