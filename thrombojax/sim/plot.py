"""A quick picture of a simulation: a few frames, vessel wall and clot, equal axis scaling."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from thrombojax.io.hdf5 import Simulation
from thrombojax.types import NodeType

__all__ = ["plot_simulation"]


def plot_simulation(sim: Simulation, path: str | Path, *, n_panels: int = 4) -> Path:
    """Write a PNG of ``n_panels`` frames spread over the simulation.

    Wall points are drawn small and grey, clot nodes coloured by frame; the three axes share
    one scale (``set_box_aspect`` from the data ranges), so bends are not distorted.

    Returns:
        The path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pos = np.asarray(sim.positions)
    clot = np.asarray(sim.node_type) == NodeType.CLOT
    frames = np.unique(np.linspace(0, len(pos) - 1, n_panels).round().astype(int))
    wall = pos[0, ~clot]
    wall = wall[:: max(1, len(wall) // 4000)]
    lo, hi = pos.reshape(-1, 3).min(0), pos.reshape(-1, 3).max(0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo).max()
    fig = plt.figure(figsize=(4.0 * len(frames), 4.2))
    for k, t in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), k + 1, projection="3d")
        ax.computed_zorder = False  # draw the clot over the wall, whatever the view
        ax.scatter(*wall.T, s=0.5, c="0.4", alpha=0.25, depthshade=False, zorder=1)
        ax.scatter(*pos[t, clot].T, s=2.0, c="crimson", depthshade=False, zorder=2)
        for i, setter in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            setter(centre[i] - half, centre[i] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_title(f"{sim.name}: frame {t}/{len(pos) - 1}", fontsize=9)
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
