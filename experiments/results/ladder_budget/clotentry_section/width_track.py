"""Along the true clot's track: does the vessel's width at the clot follow the clot's speed?
Writes ``OUT.json`` and prints one line per simulation. Run from the repository root::

    python experiments/results/ladder_budget/clotentry_section/width_track.py [--nodes N] \\
        OUT.json DATA NAME1,NAME2,...

Per simulation, every 4th frame from the dataset's first rolled-out frame: the clot's speed
(its centroid's step to the next frame), the section width
(``thrombojax.graph.section.clot_section_features``) and the clearance
(``thrombojax.graph.clearance.clot_clearance``), both at 1 vessel radius, on ``N`` nodes
drawn once per simulation (default 2,048, the rollouts' count; a uniform draw with seed 0, not
the rollouts' clot-fraction-keeping ``thrombojax.data.augment.subsample_indices``: kept so that
the committed ``width_track.json`` reproduces); the squeeze, the clot's
rest radius (the largest distance of a clot node from the clot's long axis in frame 0, all
nodes) over the width; their Pearson correlations with the speed, within each simulation and
pooled over all of them. No model is involved: this is the data alone. The JSON keeps the
environment it was measured in (``measured``).
"""

import json
import pathlib
import sys

import jax
import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.tables import environment
from thrombojax.graph.clearance import clot_clearance
from thrombojax.graph.section import clot_section_features
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text
from thrombojax.types import NodeType, clot_mask


def track(ds, name: str, nodes: int, every: int = 4) -> dict:
    """Speed, width and clearance (vessel radii) along ``name``'s true track."""
    r = vessel_radius(ds)
    pos, nt = ds.positions(name), ds.node_type(name)
    idx = np.sort(np.random.default_rng(0).choice(pos.shape[1], min(nodes, pos.shape[1]),
                                                  replace=False))
    nt, mask = nt[idx], np.ones(len(idx), bool)
    clot = clot_mask(nt, mask)
    width = jax.jit(lambda x: clot_section_features(x, nt, mask, scale=r))
    clearance = jax.jit(lambda x: clot_clearance(x, nt, mask, scale=r))
    rows = {"frame": [], "speed_r": [], "width_r": [], "clearance_r": []}
    for t in range(max(study.skip_frames(ds), 1), pos.shape[0] - 1, every):
        x = pos[t, idx]
        rows["frame"].append(t)
        rows["speed_r"].append(float(np.linalg.norm(pos[t + 1, idx][clot].mean(0)
                                                    - x[clot].mean(0)) / r))
        rows["width_r"].append(float(np.asarray(width(x))[clot, 0][0]))
        rows["clearance_r"].append(float(np.asarray(clearance(x))[clot, 0][0]))
    rest = ds.positions(name, 0)[ds.node_type(name) == NodeType.CLOT]
    rest = rest - rest.mean(0)
    axis = np.linalg.eigh(rest.T @ rest)[1][:, -1]
    rows["rest_radius_r"] = float(np.linalg.norm(rest - np.outer(rest @ axis, axis),
                                                 axis=1).max() / r)
    rows["squeeze"] = (rows["rest_radius_r"] / np.asarray(rows["width_r"])).tolist()
    speed = np.asarray(rows["speed_r"])
    return rows | {f"corr_speed_{k}": float(np.corrcoef(speed, rows[key])[0, 1])
                   for k, key in (("width", "width_r"), ("clearance", "clearance_r"),
                                  ("squeeze", "squeeze"))}


def main() -> None:
    argv, nodes = sys.argv[1:], 2048
    if argv[:1] == ["--nodes"]:
        nodes, argv = int(argv[1]), argv[2:]
    if len(argv) != 3:
        sys.exit(__doc__)
    out, data, names = pathlib.Path(argv[0]), argv[1], argv[2].split(",")
    if out.exists():
        sys.exit(f"{out} exists; move it away to measure again")
    ds = open_dataset(data)
    result = {"dataset": data, "n_nodes": nodes, "simulations": {}}
    for name in names:
        rec = track(ds, name, nodes)
        result["simulations"][name] = rec
        print(f"{name}: width {min(rec['width_r']):.2f}-{max(rec['width_r']):.2f} r, rest "
              f"radius {rec['rest_radius_r']:.2f} r, mean speed {np.mean(rec['speed_r']):.3f} "
              f"r/frame; speed correlates {rec['corr_speed_width']:+.2f} with the width, "
              f"{rec['corr_speed_clearance']:+.2f} with the clearance, "
              f"{rec['corr_speed_squeeze']:+.2f} with the squeeze", flush=True)
    sims = result["simulations"].values()
    speed = np.concatenate([s["speed_r"] for s in sims])
    result["pooled"] = {f"corr_speed_{k}": float(np.corrcoef(
        speed, np.concatenate([s[key] for s in sims]))[0, 1])
        for k, key in (("width", "width_r"), ("clearance", "clearance_r"), ("squeeze", "squeeze"))}
    print("pooled: " + ", ".join(f"{k} {v:+.2f}" for k, v in result["pooled"].items()))
    result["measured"] = environment()
    atomic_write_text(out, json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
