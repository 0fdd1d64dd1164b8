"""How far the true clot's centroid lies from the middle of the vessel's cross-section.

For every frame of the chosen simulations, the offset (across the local axis, vessel radii) of
the true clot's centroid from ``thrombojax.simulator.centring.section_centre`` on the full
simulation's rigid wall (its triangles when it has them;
``thrombojax.eval.centring_fit.centroid_offsets``): the centring guard's tolerance is picked
from the training simulations' largest offset where the section has a centre (not at an open
end, where the guard stands aside), so that it would never move a true clot of them. Writes
``OUT.json`` (every frame) and ``OUT.md`` (per simulation: the frames without a centre, and the
median, 95th percentile and largest offset of the others). Run
from the repository root::

    python experiments/results/ladder_budget/clotentry_centring/truth_offset.py \\
        OUT data/clotentry.h5 clotentry_000,clotentry_001,...
"""

import argparse
import json
import pathlib

import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.eval.centring_fit import centroid_offsets
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text


def offsets(ds, name: str, r: float) -> tuple[np.ndarray, np.ndarray]:
    """``([T] offset, [T] ok)``: the true centroid's offset from the section's middle (vessel
    radii), and whether the section has a middle there (not at an open end)."""
    sim = ds[name]
    return centroid_offsets(sim.positions, sim.node_type, sim.wall_cells, r)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=pathlib.Path)
    p.add_argument("data", type=pathlib.Path)
    p.add_argument("names")
    a = p.parse_args()
    ds = open_dataset(a.data)
    r = float(vessel_radius(ds))
    per = {n: offsets(ds, n, r) for n in a.names.split(",")}
    rows = ["| simulation | frames with a centre | no centre (open end) | median offset (r) | "
            "95th percentile (r) | largest (r) |", "|---|---|---|---|---|---|"]
    rows += [f"| {n} | {ok.sum()} | {', '.join(map(str, np.flatnonzero(~ok))) or '-'} | "
             f"{np.median(o[ok]):.3f} | {np.percentile(o[ok], 95):.3f} | {o[ok].max():.3f} |"
             for n, (o, ok) in per.items()]
    env = environment()
    text = "\n".join(rows) + "\n\n" + "\n".join(f"- {k}: {v}" for k, v in env.items()) + "\n"
    atomic_write_text(a.out.with_suffix(".md"), text)
    atomic_write_text(a.out.with_suffix(".json"), json.dumps(
        {"offset_r": {n: o.round(4).tolist() for n, (o, _) in per.items()},
         "ok": {n: ok.tolist() for n, (_, ok) in per.items()}, **env}, indent=1))
    print(text)


if __name__ == "__main__":
    main()
