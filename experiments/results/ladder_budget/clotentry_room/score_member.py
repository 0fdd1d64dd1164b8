"""Score one trained run of a ladder rung alone and guarded, as the ladder scores a rung (last
checkpoint, the run's test split, ``--nodes`` of the ladder's fixed subset), and write each
result as ``OUT/<label>/result.json`` and ``OUT/<label>_guards/result.json`` (atomically; existing
files only with ``--force``), with the command, device, versions and date.

    python score_member.py RUN DATA LABEL OUT [--nodes 2048] [--force]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3]))
from ladder_eval import evaluate_runs  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, check_targets  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="the run folder (holds config.json and checkpoints/)")
    parser.add_argument("data", help="the dataset (.h5)")
    parser.add_argument("label", help="folder name of the results (guarded: LABEL_guards)")
    parser.add_argument("out", help="folder the result folders are written into")
    parser.add_argument("--nodes", type=int, default=2048, help="nodes per simulation")
    parser.add_argument("--force", action="store_true", help="replace existing results")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    targets = {g: out / (args.label + ("_guards" if g else "")) / "result.json"
               for g in (False, True)}
    check_targets(targets.values(), force=args.force)
    for guards, path in targets.items():
        res = evaluate_runs([pathlib.Path(args.run)], args.data, guards, args.nodes,
                            which="last")
        res["record"] = {"command": "python " + " ".join(sys.argv), **environment()}
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, json.dumps(res, indent=1))
        print(f"{path}: final centroid {res['mean']['final_centroid_r']:.2f} r, "
              f"max outside {100 * res['mean']['max_outside']:.0f} %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
