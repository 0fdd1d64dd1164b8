"""Roll a rung's models out again, on this machine, from checkpoints the device trained, and
write the ladder's measures (``experiments/ladder_eval.py``, which now records the centroid
error along and across the true track and the clot's size, ``thrombojax.eval.track``) with
the environment and command.

    python experiments/results/ladder_gpu/fifth_session/track_reroll.py OUT.json \
        RUN[,RUN...] guards|alone [--dataset data/clotentry.h5] [--nodes 2048] \
        [--without containment|coherence] [--lateral-hold R]

RUN: training run folders with ``config.json`` and ``checkpoints/last`` (several: an
ensemble, rolled out as independent members with their mean guarded).
"""
import argparse
import json
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[4]
sys.path.insert(0, str(ROOT / "experiments"))
import ladder_eval  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import atomic_write_text  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("out")
parser.add_argument("runs")
parser.add_argument("guards", choices=["guards", "alone"])
parser.add_argument("--dataset", default=str(ROOT / "data" / "clotentry.h5"))
parser.add_argument("--nodes", type=int, default=2048)
parser.add_argument("--without", choices=["containment", "coherence"],
                    help="with guards: switch this one off (which guard does what)")
parser.add_argument("--lateral-hold", type=float, default=0.0,
                    help="roll out with the step's lateral hold, axis width R vessel radii "
                         "(thrombojax.graph.vessel_axis.clot_lateral_mean), on models trained "
                         "without it (default 0: the step as trained)")
args = parser.parse_args()
out = pathlib.Path(args.out)
if out.exists():
    raise SystemExit(f"track_reroll: {out} exists; not replacing it")
runs = [pathlib.Path(p) for p in args.runs.split(",")]
if args.without and args.guards != "guards":
    raise SystemExit("track_reroll: --without switches off one guard; it needs 'guards'")
step_options = None
if args.lateral_hold > 0:  # radii -> the run's scaled units
    from thrombojax.data.radius import vessel_radius
    from thrombojax.io.hdf5 import open_dataset

    scale = json.loads((runs[0] / "config.json").read_text())["scaling"]["scale"]
    step_options = {"lateral_radius": args.lateral_hold
                    * vessel_radius(open_dataset(args.dataset)) / scale}
res = ladder_eval.evaluate_runs(runs, args.dataset, args.guards == "guards", args.nodes,
                                which="last",
                                guard_options={args.without: False} if args.without else None,
                                step_options=step_options)
atomic_write_text(out, json.dumps({"environment": environment(), "step_options": step_options,
                                   "result": res}, indent=1))
for name, s in res["simulations"].items():
    print(f"{name}: final centroid {s['final_centroid_r']:.2f} r, along {s['final_along_r']:+.2f}"
          f" r, across {s['final_across_r']:.2f} r, size {s['final_size_ratio']:.3f}")
