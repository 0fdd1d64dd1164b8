"""Score trained runs as one guarded ensemble, as the ladder scores an ensemble rung (last
checkpoints, the first run's test split, ``--nodes`` of the ladder's fixed subset, the members'
mean guarded), without scoring each member alone, and write ``OUT/LABEL/result.json``
(atomically; an existing file only with ``--force``) with the command, device, versions and
date.

    python score_ensemble.py DATA LABEL OUT RUN [RUN ...] [--nodes 2048] [--force]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3]))
from ladder_eval import evaluate_runs  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, check_targets  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", help="the dataset (.h5)")
    parser.add_argument("label", help="folder name of the result")
    parser.add_argument("out", help="folder the result folder is written into")
    parser.add_argument("runs", nargs="+", help="the run folders (config.json, checkpoints/)")
    parser.add_argument("--nodes", type=int, default=2048, help="nodes per simulation")
    parser.add_argument("--force", action="store_true", help="replace an existing result")
    args = parser.parse_args(argv)
    path = pathlib.Path(args.out) / args.label / "result.json"
    check_targets([path], force=args.force)
    start = time.perf_counter()
    res = evaluate_runs([pathlib.Path(r) for r in args.runs], args.data, True, args.nodes,
                        which="last")
    res["seconds"] = time.perf_counter() - start
    res["runs"] = args.runs
    res["record"] = {"command": "python " + " ".join(sys.argv), **environment()}
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, json.dumps(res, indent=1))
    per_sim = ", ".join(f"{n} {s['final_centroid_r']:.2f} r, along {s['final_along_r']:+.2f}"
                        for n, s in res["simulations"].items())
    print(f"{path}: {len(args.runs)} members, final centroid "
          f"{res['mean']['final_centroid_r']:.2f} r ({per_sim}), max outside "
          f"{100 * res['mean']['max_outside']:.0f} %, {res['seconds']:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
