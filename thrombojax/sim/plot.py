"""A quick picture of a simulation: a few frames, vessel wall and clot, equal axis scaling."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from thrombojax.io.hdf5 import Simulation
from thrombojax.types import NodeType

__all__ = ["plot_simulation"]


def plot_simulation(sim: Simulation, path: str | Path, *, n_panels: int = 4,
                    units: str = "") -> Path:
    """Write a PNG of ``n_panels`` frames spread over the simulation.

    One view box (the whole trajectory, equal axes), one camera across the vessel's plane, wall
    points small and grey, the clot drawn above them in red; axis labels carry ``units``, panel
    titles the frame and its time ``frame * dt``, and a legend names wall and clot.

    Returns:
        The path written (atomically).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from thrombojax.plotting.scene import (
        camera_angles,
        draw_clot,
        draw_wall,
        save_atomic,
        setup_axes,
        view_limits,
        wall_subset,
    )

    pos = np.asarray(sim.positions, np.float64)
    clot = np.asarray(sim.node_type) == NodeType.CLOT
    frames = np.unique(np.linspace(0, len(pos) - 1, n_panels).round().astype(int))
    wall = wall_subset(sim.node_type, 4000)
    lim = view_limits(pos, sim.node_type)
    angles = camera_angles(pos[0, wall] if wall.size else pos[0])
    dt = sim.attrs.get("dt")
    units = units or "length unit"
    fig = plt.figure(figsize=(3.9 * len(frames), 4.6), dpi=110)
    for k, t in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), k + 1, projection="3d")
        setup_axes(ax, lim, units, angles)
        draw_wall(ax, pos[0, wall])
        draw_clot(ax, pos[t, clot], color="crimson", size=3.0)
        when = f", t = {t * float(dt):.3g}" if dt is not None else ""
        ax.set_title(f"frame {t}/{len(pos) - 1}{when}", fontsize=9)
    handles = [Line2D([], [], ls="", marker="o", color="0.5", label="vessel wall"),
               Line2D([], [], ls="", marker="o", color="crimson", label="clot")]
    fig.legend(handles=handles, loc="lower center", ncol=2, frameon=False, fontsize=9)
    fig.suptitle(f"{sim.name}: {int(clot.sum())} clot nodes, {int((~clot).sum())} wall nodes "
                 f"(lengths in {units})", fontsize=10)
    fig.subplots_adjust(left=0.01, right=0.97, bottom=0.1, top=0.86, wspace=0.12)
    try:
        return save_atomic(lambda tmp: fig.savefig(tmp, format="png"), path)
    finally:
        plt.close(fig)
