"""What ``--coherence-tolerance auto`` gives on each dataset: the coherence tolerance fitted on a
run's training simulations, beside how far each simulation's true clot strays. No model. Run from
the repository root::

    python experiments/results/ladder_budget/coherence_auto/fit_table.py OUT.md \\
        RUN_CONFIG.json[=DATA] ... [--force]

Each argument is a run's ``config.json`` (its ``split.train`` names the training simulations)
and, after ``=``, the dataset to read (default: the run's own ``dataset``). Per dataset: the
tolerance ``auto`` fits (``thrombojax.eval.coherence_fit.fit_coherence``, the 95th percentile of
the training clots' (node, frame) distances from a rigid copy of the rollout's first frame), the
99th percentile and the largest distance among them; and per simulation of the whole dataset
the largest distance, to show what a tolerance leaves alone on the held-out ones.
"""

import argparse
import json
import pathlib

import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.coherence_fit import clot_deviations, fit_coherence
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=pathlib.Path, help="the Markdown table to write")
    parser.add_argument("runs", nargs="+", help="RUN_CONFIG.json[=DATA]")
    parser.add_argument("--force", action="store_true", help="replace an existing OUT")
    args = parser.parse_args()
    check_targets([args.out], force=args.force)
    fits, sims = [], []
    for spec in args.runs:
        config_path, _, data = spec.partition("=")
        config = json.loads(pathlib.Path(config_path).read_text())
        data = data or config["dataset"]
        ds = open_dataset(data)
        start, r = study.skip_frames(ds), float(vessel_radius(ds))
        train = config["split"]["train"]
        fit = fit_coherence(ds, train, r, start)
        pooled = np.concatenate([clot_deviations(ds[n].positions, ds[n].node_type, start, r)
                                 .ravel() for n in train])
        fits.append([pathlib.Path(data).name, len(train), start, fit["coherence_r"],
                     float(np.quantile(pooled, 0.99)), fit["largest_r"]])
        for name in ds.names:
            dev = clot_deviations(ds[name].positions, ds[name].node_type, start, r)
            role = next((k for k in ("train", "val", "test") if name in config["split"][k]), "-")
            sims.append([pathlib.Path(data).name, name, role, float(dev.max()),
                         start + 1 + int(dev.max(1).argmax()), float(np.quantile(dev, 0.95))])
        print(" | ".join(str(v) for v in fits[-1]), flush=True)
    atomic_write_text(args.out, (
        "# The coherence tolerance `auto` fits, per dataset\n\n"
        + markdown_table(["dataset", "training simulations", "first frame",
                          "auto: 95th percentile (r)", "99th percentile (r)", "largest (r)"], fits)
        + "\n## Every simulation's true clot against a rigid copy of the first frame\n\n"
        + markdown_table(["dataset", "simulation", "split", "largest (r)", "at frame",
                          "95th percentile (r)"], sims)
        + "\n" + "".join(f"- {k}: {v}\n" for k, v in environment().items())))


if __name__ == "__main__":
    main()
