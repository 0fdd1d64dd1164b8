"""What the true clot's speed follows, on the data alone: per simulation of a dataset, over the
rollout window (from the dataset's ``skip_frames``), the correlation of the clot's speed with its
length along its motion, with the clearance at its centroid and with the clearance 1 r ahead of
its front; and the means over rollout steps 20-40. No model is run; the output is written
atomically and replaced only with ``--force``. Run from the repository root::

    python experiments/results/ladder_budget/clotentry_speed_room/clot_length.py \\
        data/clotentry.h5 \\
        --out experiments/results/ladder_budget/clotentry_speed_room/clot_length.md

Definitions, per frame t of the window (the clot nodes and the rigid wall's nodes by their node
type; distances in vessel radii, ``thrombojax.data.radius.vessel_radius``):

- speed: the clot centroid's displacement from t to t+1 (``centroid_speed`` of
  ``experiments/clot_speed.py``);
- length: the 5-95 % range of the clot nodes' offsets from the centroid along the direction of
  that displacement;
- clearance: the distance from the centroid to the nearest wall node of the first frame (as
  ``experiments/clot_speed.py`` measures it);
- ahead: the same from the point 1 r ahead (along the motion) of the mean of the clot nodes in
  the top 5 % along the motion (the clot's front).

Correlations are of 10-frame moving means within each simulation, as in ``../clotentry_room/``.
"""

from __future__ import annotations

import argparse
import datetime
import pathlib
import sys

import numpy as np
from scipy.spatial import cKDTree

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.types import NodeType, clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "clotentry_room"))
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3]))
from clot_speed import centroid_speed, clearance  # noqa: E402
from speed_profile import smooth  # noqa: E402

COLUMNS = ("length", "clearance", "ahead")


def profiles(positions: np.ndarray, node_type: np.ndarray, skip: int, radius: float) -> dict:
    """Per-step speed, length, clearance and clearance ahead (vessel radii) of one simulation's
    rollout window: steps from frames ``skip .. T - 2`` to the next frame."""
    if positions.shape[0] < skip + 2:
        raise ValueError(f"{positions.shape[0]} frames leave no rollout window after "
                         f"skip_frames {skip}")
    clot = clot_mask(node_type)
    wall = positions[0][node_type == NodeType.VESSEL].astype(np.float64)
    if not len(wall) or not clot.any():
        raise ValueError("needs clot nodes and vessel (wall) nodes")
    cen, speed = centroid_speed(positions, clot)
    tree, nodes = cKDTree(wall), positions[:, clot].astype(np.float64)
    out = {"speed": speed[skip:] / radius, "clearance": clearance(cen[skip:-1], wall) / radius,
           "length": [], "ahead": []}
    for t in range(skip, positions.shape[0] - 1):
        d = cen[t + 1] - cen[t]
        u = d / max(float(np.linalg.norm(d)), 1e-30)
        along = (nodes[t] - cen[t]) @ u
        lo, hi = np.quantile(along, [0.05, 0.95])
        front = nodes[t][along >= hi].mean(axis=0)
        out["length"].append((hi - lo) / radius)
        out["ahead"].append(tree.query(front + u * radius)[0] / radius)
    return {k: np.asarray(v) for k, v in out.items()}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dataset", help="HDF5 dataset")
    p.add_argument("--out", type=pathlib.Path, required=True, help="markdown table to write")
    p.add_argument("--width", type=int, default=10, help="moving-mean width in frames (10)")
    p.add_argument("--force", action="store_true", help="replace an existing output")
    args = p.parse_args()
    check_targets([args.out], force=args.force)
    ds = open_dataset(args.dataset)
    skip, radius = max(study.skip_frames(ds), 1), vessel_radius(ds)
    lines = ["# What the true clot's speed follows (data alone; r = vessel radii)", "",
             "| simulation | corr(speed, length) | corr(speed, clearance) | corr(speed, ahead) "
             "| steps 20-40: speed (r/frame) | length (r) | clearance (r) | ahead (r) |",
             "|---|---|---|---|---|---|---|---|"]
    for name in ds.names:
        try:
            prof = profiles(np.asarray(ds.positions(name)), np.asarray(ds.node_type(name)),
                            skip, radius)
        except ValueError as err:
            raise SystemExit(f"{args.dataset}: simulation {name!r}: {err}") from None
        corr = [np.corrcoef(smooth(prof["speed"], args.width),
                            smooth(prof[k], args.width))[0, 1] for k in COLUMNS]
        seg = [prof[k][20:40].mean() for k in ("speed", *COLUMNS)]
        lines.append(f"| {name} | " + " | ".join(f"{c:+.2f}" for c in corr)
                     + f" | {seg[0]:.3f} | " + " | ".join(f"{v:.2f}" for v in seg[1:]) + " |")
    env = environment()
    lines += ["", f"- command: python {' '.join(sys.argv)}",
              f"- date: {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}",
              f"- dataset: {args.dataset} (skip_frames {skip}, vessel radius {radius:g}; "
              f"moving mean of {args.width} frames)",
              f"- cpu: {env.get('cpu')}; load {env.get('load_avg_1_5_15')}; python "
              f"{env.get('python')}, jax {env.get('jax')}, numpy {np.__version__}",
              "- no model run: read from the dataset"]
    atomic_write_text(args.out, "\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
