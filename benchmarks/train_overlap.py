"""Training-loop throughput with and without the host/device overlap (issue 17).

:func:`thrombojax.train.loop.train` reads a step's metrics one step behind, after dispatching
the next step, so the host assembles the next batch (:func:`thrombojax.data.batching.make_batch`:
window gathering and node subsampling in numpy, then the transfer) while the device computes.
This runs the same short training twice per round, with the overlap and with every step read at
once (the loop's private ``_OVERLAP`` switch), for ``--rounds`` rounds (which goes first
alternates), and reports the steps per second after the first two epochs: steps of epochs
``3..E`` over the wall time between the ends of epochs 2 and ``E`` (``time_s`` of
``metrics.jsonl``, taken before each epoch's validation, so epoch 2's interval still holds the
compilation of the evaluation step; validation and the per-epoch checkpoint are inside the
timed interval, the same for both). The two runs give the same losses
(``tests/test_train_overlap.py``; checked here too).

Data: synthetic simulations (a bent tube of vessel nodes and a clot that drifts along it,
scaled to about [-1, 1]); the speed depends on the node count, not on the physics.

Usage::

    python benchmarks/train_overlap.py [--model mgn] [--nodes 1000] [--epochs 3] [--rounds 3]
                                       [--model-config '{"hidden": 32}'] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
from pathlib import Path

import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.io.hdf5 import Simulation, write_dataset
from thrombojax.train import loop
from thrombojax.types import NodeType

__all__ = ["synthetic_simulation", "run_once", "main"]


def synthetic_simulation(i: int, n_nodes: int, n_frames: int) -> Simulation:
    """A bent tube wall (80 % of the nodes) with a clot blob drifting along it."""
    rng = np.random.default_rng(i)
    n_clot = max(1, n_nodes // 5)
    n_wall = n_nodes - n_clot
    s, phi = rng.uniform(0, 1, n_wall), rng.uniform(0, 2 * np.pi, n_wall)
    bend = 0.5 * np.pi * s
    centre = np.stack([np.sin(bend), 1 - np.cos(bend), 0 * s], 1)
    normal = np.stack([-np.sin(bend), np.cos(bend), 0 * s], 1)
    wall = centre + 0.2 * (np.cos(phi)[:, None] * normal + np.sin(phi)[:, None] * [0, 0, 1])
    clot = rng.normal(0, 0.05, (n_clot, 3)) + [0.3, 0.05, 0.0]
    t = np.arange(n_frames)[:, None, None]
    moving = clot[None] + (0.01 + 0.001 * i) * t**1.5 * np.array([1.0, 0.4, 0.0])
    pos = np.concatenate([np.broadcast_to(wall, (n_frames, n_wall, 3)), moving], axis=1)
    node_type = np.array([NodeType.VESSEL] * n_wall + [NodeType.CLOT] * n_clot, np.int8)
    return Simulation(name=f"sim{i}", positions=pos.astype(np.float32), node_type=node_type,
                      attrs={"dt": 0.1})


def run_once(dataset: Path, out: Path, overlap: bool, args) -> dict:
    """One training run; returns steps/s after epoch 2 and the per-epoch training losses."""
    loop._OVERLAP = overlap
    try:
        loop.train(dataset, args.model, out, progress=False, epochs=args.epochs,
                   batch_size=args.batch_size, n_val=1, n_test=1, warmup_epochs=1.0,
                   model_config=json.loads(args.model_config), tiny=args.tiny)
    finally:
        loop._OVERLAP = True
    records = [json.loads(ln) for ln in (out / "metrics.jsonl").read_text().splitlines()]
    steps = records[-1]["step"] - records[1]["step"]
    return {"steps_per_s": steps / (records[-1]["time_s"] - records[1]["time_s"]),
            "losses": [r["train_loss"] for r in records], "steps": steps}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--model", default="mgn")
    parser.add_argument("--model-config", default="{}", help="JSON overrides of the config")
    parser.add_argument("--tiny", action="store_true", help="start from the tiny config")
    parser.add_argument("--nodes", type=int, default=1000, help="nodes per simulation")
    parser.add_argument("--frames", type=int, default=14)
    parser.add_argument("--sims", type=int, default=5, help="simulations (1 val, 1 test)")
    parser.add_argument("--batch-size", type=int, default=4)
    parser.add_argument("--epochs", type=int, default=4, help=">= 3 (two are not timed)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", default=None, help="markdown file to write")
    args = parser.parse_args()
    if args.epochs < 3:
        parser.error("--epochs must be >= 3")
    env = environment()
    out = [f"# benchmarks/train_overlap.py on {env['device']}", "", "```"]
    out += [f"# {k}: {v}" for k, v in env.items()] + ["```", ""]
    results = {True: [], False: []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sims = [synthetic_simulation(i, args.nodes, args.frames) for i in range(args.sims)]
        dataset = write_dataset(tmp / "synthetic.h5", sims, name="synthetic", source="bench")
        for r in range(args.rounds):
            for overlap in (True, False) if r % 2 else (False, True):
                res = run_once(dataset, tmp / f"run_{r}_{overlap}", overlap, args)
                res["load"] = [round(x, 2) for x in os.getloadavg()]
                results[overlap].append(res)
                print(f"# round {r} overlap={overlap}: {res}", flush=True)
    same = all(a["losses"] == b["losses"] for a, b in zip(results[True], results[False],
                                                          strict=True))
    out += [f"{args.model} (tiny: {args.tiny}, overrides {args.model_config}), {args.sims} "
            f"simulations x {args.nodes} nodes x {args.frames} frames, batch {args.batch_size}, "
            f"{args.epochs} epochs ({results[True][0]['steps']} timed steps per run); "
            f"{args.rounds} rounds alternating the two. Same training losses: {same}.", "",
            "| loop | steps/s median | range | per round | load after each run |",
            "|---|---|---|---|---|"]
    for overlap, label in ((False, "read every step at once"), (True, "one step behind")):
        rates = [x["steps_per_s"] for x in results[overlap]]
        out.append(f"| {label} | {statistics.median(rates):.3f} | {min(rates):.3f}-"
                   f"{max(rates):.3f} | {', '.join(f'{x:.3f}' for x in rates)} | "
                   f"{[x['load'] for x in results[overlap]]} |")
    ratios = [a["steps_per_s"] / b["steps_per_s"]
              for a, b in zip(results[True], results[False], strict=True)]
    out += ["", f"speed-up per round (behind / at once): {', '.join(f'{x:.3f}' for x in ratios)}"
            f"; median {statistics.median(ratios):.3f}"]
    print("\n".join(out))
    if args.out:
        Path(args.out).write_text("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
