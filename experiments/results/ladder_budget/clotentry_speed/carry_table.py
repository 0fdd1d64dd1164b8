"""How much of a speed error each model keeps, beside where its rollout ends: reads the rows'
JSON (``cross_eval.py``'s ``LABEL.json`` or the ladder's ``RUNG/result.json``) and writes one
table with, per held-out simulation, the speed carry (``thrombojax.eval.drift.speed_carry``:
1 keeps the error, 0 pulls the speed back in one step), the final centroid error and its part
along the true track, the centroid error 20 steps before the end (before the clot leaves the
vessel), the rollout's mean speed against the truth's and the correlation of their moving means.
No model is run; the output is written atomically and replaced only with ``--force``::

    python carry_table.py --out table_carry.md PATH[=LABEL] ...
"""

from __future__ import annotations

import argparse
import datetime
import json
import pathlib
import sys

import numpy as np

from thrombojax.io.outputs import atomic_write_text, check_targets

# the moving mean of the speed profiles in ../clotentry_room/ (the same smoothing)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "clotentry_room"))
from speed_profile import smooth  # noqa: E402


def rows(result: dict, label: str, width: int) -> list[str]:
    """The table's rows of one result: one per simulation, then their mean."""
    out, cols = [], []
    for name, sim in result["simulations"].items():
        speed, true = np.asarray(sim["speed_per_step_r"]), np.asarray(sim["speed_true_per_step_r"])
        carry = sim.get("speed_carry", float("nan"))
        vals = [carry, sim["final_centroid_r"], sim["final_along_r"],
                float(np.asarray(sim["centroid_per_step_r"])[-21]), float(speed.mean()),
                float(true.mean()), float(np.corrcoef(smooth(speed, width),
                                                      smooth(true, width))[0, 1]),
                100.0 * sim["max_outside"]]
        cols.append(vals)
        out.append(f"| {label} | {name} | " + " | ".join(_fmt(vals, True)) + " |")
    table = np.asarray(cols, float)
    table[:, 2] = np.abs(table[:, 2])  # the mean row: how far along, either way
    mean = table.mean(axis=0)
    out.append(f"| {label} | **mean** | " + " | ".join(_fmt(list(mean), False)) + " |")
    return out


def _fmt(v: list[float], signed: bool) -> list[str]:
    carry = "-" if np.isnan(v[0]) else f"{v[0]:.2f}"
    along = f"{v[2]:+.2f}" if signed else f"{v[2]:.2f}"
    return [carry, f"{v[1]:.2f}", along, f"{v[3]:.2f}", f"{v[4]:.3f}", f"{v[5]:.3f}",
            f"{v[6]:+.2f}", f"{v[7]:.1f} %"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", nargs="+", help="row JSON files or rung folders holding "
                        "result.json, each optionally PATH=LABEL (default: the file's stem or "
                        "the folder's name)")
    parser.add_argument("--out", required=True, help="the table's file (Markdown)")
    parser.add_argument("--smooth", type=int, default=10, help="frames of the moving mean")
    parser.add_argument("--force", action="store_true", help="replace an existing output")
    args = parser.parse_args(argv)
    if args.smooth < 1:
        parser.error("--smooth must be >= 1")
    out = pathlib.Path(args.out)
    check_targets([out], force=args.force)
    lines = []
    for arg in args.rows:
        where, _, label = arg.partition("=")
        path = pathlib.Path(where)
        path = path / "result.json" if path.is_dir() else path
        if not path.is_file():
            raise SystemExit(f"{path}: no such row file")
        lines += rows(json.loads(path.read_text()), label or (
            path.parent.name if path.name == "result.json" else path.stem), args.smooth)
    text = "\n".join([
        "# Speed carry against the rollout's end (held-out simulations; r = vessel radii)", "",
        "| row | simulation | speed carry | final centroid error (r) | along the track (r; + "
        "ahead) | centroid error 20 steps before the end (r) | rollout mean speed (r/frame) | "
        f"true mean speed | corr of {args.smooth}-frame mean speeds | max clot outside |",
        "|---|---|---|---|---|---|---|---|---|---|", *lines, "",
        "Speed carry is measured on the model alone (the step given a clot-wide speed error of "
        "5 % in its input); guarded rows show the same model's value.", "",
        f"- command: python {' '.join(sys.argv)}",
        f"- date: {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}",
        "- no model run: read from the rows' JSON", ""])
    atomic_write_text(out, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
