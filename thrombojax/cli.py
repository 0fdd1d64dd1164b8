"""The ``thrombojax`` command. Thin: every subcommand parses flags and calls one library function.

Errors that thrombojax raises on purpose (:class:`thrombojax.errors.ThrombojaxError`) and
missing files are printed as one line and exit with status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable, Sequence

from thrombojax.cli_types import angle, float_above, float_at_least, int_at_least
from thrombojax.errors import ThrombojaxError

__all__ = ["main", "build_parser"]

_Registrar = Callable[["argparse._SubParsersAction"], None]

# ---- subcommands: each `_add_<name>` registers one parser and sets `func` ------------------

_REGISTRARS: list[_Registrar] = []

# argument types: numbers are checked (finite, in range) when the flags are parsed
_NN_INT, _POS_INT = int_at_least(0), int_at_least(1)
_NN_FLOAT, _POS_FLOAT = float_at_least(0.0), float_above(0.0)


def _output_flags(p, force_help: str) -> None:
    """``--force`` and ``--quiet``: the same two flags on every writing command."""
    p.add_argument("--force", action="store_true", help=f"{force_help} (never an input file)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_info(sub) -> None:
    p = sub.add_parser(
        "info",
        help="summarise a dataset file (and validate every simulation)",
        description=(
            "Read and validate every simulation of a dataset file and print a summary: "
            "simulations, frames, nodes, clot fraction, bounding box, dt, solver and reference "
            "wall times. A malformed file gives a one-line error and exit status 2."
        ),
    )
    p.add_argument("file", metavar="FILE", help="dataset .h5 file")
    p.add_argument("--progress", action="store_true", help="show a progress bar")
    p.set_defaults(func=_run_info)


def _run_info(args) -> int:
    from thrombojax.io.info import describe_dataset

    print(describe_dataset(args.file, progress=args.progress))
    return 0


def _import_common(p) -> None:
    p.add_argument("--out", required=True, metavar="FILE", help="dataset .h5 file to write")
    p.add_argument("--name", action="append", metavar="NAME", dest="names",
                   help="simulation name; repeat once per simulation, in order "
                        "(default: folder / file names)")
    p.add_argument("--dataset-name", metavar="NAME", help="dataset name (default: FILE's stem)")
    p.add_argument("--dt", type=_POS_FLOAT, help="time step between stored frames, stored "
                   "per sim")
    p.add_argument("--reference-time", type=_POS_FLOAT, metavar="SECONDS",
                   help="recorded solver wall time per simulation (e.g. Abaqus), for speed-ups")
    p.add_argument("--units", required=True, metavar="UNIT",
                   help="length unit of the coordinates, e.g. mm, m or 'vessel radius' "
                        "(stored in the dataset, shown in every report and picture)")
    _output_flags(p, "overwrite FILE if it exists")


def _add_import(sub) -> None:
    p = sub.add_parser(
        "import",
        help="import solver output (VTU/VTK/XDMF series, Abaqus .inp + frames) into a dataset",
        description=(
            "Convert existing simulation output into one thrombojax dataset file (several "
            "simulations per call). Every simulation is validated; the file is written "
            "atomically. See 'thrombojax import vtu --help' and 'thrombojax import abaqus --help'."
        ),
    )
    kinds = p.add_subparsers(dest="kind", metavar="KIND", required=True)
    m = kinds.add_parser(
        "vtu",
        aliases=["mesh"],
        help="one simulation per folder / quoted glob of VTU, VTK or XDMF frames, or per "
             ".pvd / XDMF time-series file",
        description=(
            "Each SOURCE is one simulation: a folder of frame files (.vtu/.vtk/.xdmf/.xmf, one "
            "per frame, same points, natural file-name order), a quoted glob like "
            "'run1/*.vtu', or one time-series file (.pvd, or .xdmf with a temporal collection, "
            "as 'thrombojax export' writes them; their times give --dt). Names: the folder's "
            "name or the file's stem. Node type: from the point-data array "
            "--node-type-array (default: 'node_type' when present, values 0 vessel / 1 clot), "
            "else from the cells of the first frame (tetra = clot, triangle = vessel wall)."
        ),
    )
    m.add_argument("sources", nargs="+", metavar="SOURCE",
                   help="frames folder, quoted glob, or .pvd / .xdmf series file")
    m.add_argument("--node-type-array", metavar="ARRAY",
                   help="point-data array with the node type (then required in every source)")
    _import_common(m)
    m.set_defaults(func=_run_import_mesh)
    a = kinds.add_parser(
        "abaqus",
        help="Abaqus .inp mesh + per-frame node coordinates exported from the .odb",
        description=(
            "One simulation per --frames: a [T, N, 3] .npy file, or a folder of frame_0000.npy "
            "([N, 3]) or frame_0000.csv files (rows 'x,y,z' in .inp node order, or "
            "'label,x,y,z' in any order; optional header). The .inp must be flat (one *Node "
            "block). Clot / vessel nodes come from element or node sets: --clot-set / "
            "--vessel-set (each repeatable; --clot-set alone makes every other node vessel), "
            "by default sets named like *CLOT* / *VESSEL*, *WALL*, *ARTERY*, else element "
            "types (tetrahedra C3D4/C3D10 = clot; triangle and quad shell, surface, membrane "
            "or rigid elements S3, M3D3, SFM3D3, R3D3, S4R, M3D4, SFM3D4, R3D4 ... = vessel "
            "wall). Nodes in no element (a rigid body's reference node) are dropped; the "
            "frames may list them or not. Messages name nodes by their Abaqus label. Names: "
            "the --frames folder's name or file stem."
        ),
    )
    a.add_argument("--inp", action="append", required=True, metavar="FILE",
                   help=".inp mesh; once for all simulations or once per --frames")
    a.add_argument("--frames", action="append", required=True, metavar="PATH",
                   help="coordinates of one simulation (.npy or folder); repeat per simulation")
    a.add_argument("--clot-set", action="append", metavar="SET",
                   help="clot element/node set; repeat for several sets")
    a.add_argument("--vessel-set", action="append", metavar="SET",
                   help="vessel element/node set; repeat for several sets (default with "
                        "--clot-set: all other nodes)")
    _import_common(a)
    a.set_defaults(func=_run_import_abaqus)


def _run_import_mesh(args) -> int:
    from thrombojax.io.meshio_import import import_mesh_series

    out = import_mesh_series(
        args.sources, args.out, names=args.names, dataset_name=args.dataset_name,
        node_type_array=args.node_type_array, dt=args.dt,
        reference_wall_time_s=args.reference_time, units=args.units, overwrite=args.force,
        progress=not args.quiet,
    )
    print(f"wrote {out}")
    return 0


def _run_import_abaqus(args) -> int:
    from thrombojax.io.abaqus import import_abaqus

    out = import_abaqus(
        args.inp, args.frames, args.out, names=args.names, dataset_name=args.dataset_name,
        clot_sets=args.clot_set, vessel_sets=args.vessel_set, dt=args.dt,
        reference_wall_time_s=args.reference_time, units=args.units, overwrite=args.force,
        progress=not args.quiet,
    )
    print(f"wrote {out}")
    return 0


_REGISTRARS += [_add_info, _add_import]


# ---- generate ----------------------------------------------------------------------------


def _add_generate(sub) -> None:
    p = sub.add_parser(
        "generate",
        help="run the built-in solver and write a dataset",
        description=(
            "Simulate a clot driven through a rigid vessel (explicit FEM in JAX) for every "
            "simulation of a preset and write the HDF5 dataset. Presets: bendvessel (20 rotated "
            "bent tubes, 41 frames), clotentry (10 tortuous vessels, 201 frames), "
            "bendvessel-tiny, clotentry-tiny (for tests)."
        ),
    )
    p.add_argument("preset", help="bendvessel | clotentry | bendvessel-tiny | clotentry-tiny")
    p.add_argument("--out", required=True, help="output .h5 file")
    p.add_argument("--sims", type=_POS_INT, default=None,
                   help="number of simulations (default: all)")
    p.add_argument("--seed", type=_NN_INT, default=0, help="dataset seed (same seed, same arrays)")
    p.add_argument("--plot", action="store_true",
                   help="also write a picture of the first simulation (bv.h5 -> bv.png)")
    _output_flags(p, "replace an existing output file")
    p.set_defaults(func=_run_generate)


def _run_generate(args) -> int:
    from thrombojax.sim.generate import generate_dataset

    out = generate_dataset(
        args.preset, args.out, n_sims=args.sims, seed=args.seed, plot=args.plot,
        progress=not args.quiet, force=args.force,
    )  # fmt: skip
    print(f"wrote {out}")
    if args.plot:
        print(f"wrote {out.with_suffix('.png')}")
    return 0


_REGISTRARS += [_add_generate]


# ---- train -------------------------------------------------------------------------------


def _add_train(sub) -> None:
    p = sub.add_parser(
        "train",
        help="train a surrogate (MeshGraphNet, Transolver, Erwin) on a dataset",
        description=(
            "Train a step-by-step surrogate as the study did: AdamW with linear warm-up then "
            "cosine decay, masked MSE on clot nodes, random rotations, optional node subsampling "
            "and BaryCentricSampling. Writes DIR/config.json, DIR/checkpoints/{best,last}, "
            "DIR/metrics.jsonl and DIR/loss.png. Options left out take the --config file's "
            "values, else the study's (each model's batch size and learning rate)."
        ),
    )
    p.add_argument("--dataset", metavar="FILE", help="dataset .h5 file (default: the dataset of "
                   "a run's config.json given as --config)")
    p.add_argument("--model", help="mgn | transolver | erwin (default: the model of a run's "
                   "config.json given as --config)")
    p.add_argument("--out", required=True, metavar="DIR", help="run directory to write")
    p.add_argument("--config", metavar="FILE", help="JSON training config (TrainConfig keys), "
                   "or a run's config.json to repeat that run")
    p.add_argument("--resume", action="store_true", help="continue the run in DIR exactly")
    p.add_argument("--epochs", type=_POS_INT, help="epochs (study: 300)")
    p.add_argument("--batch-size", type=_POS_INT, help="samples per step (study: 8 mgn/erwin, 16 "
                   "transolver); a multiple of the number of devices")
    p.add_argument("--lr", type=_POS_FLOAT,
                   help="peak learning rate (study: 1e-3 mgn, 1e-4 others)")
    p.add_argument("--warmup-epochs", type=_NN_FLOAT, help="linear warm-up epochs (study: 10)")
    p.add_argument("--radius", type=_POS_FLOAT, help="graph radius in scaled coordinates (a "
                   "model config field)")
    p.add_argument("--max-rotation", type=angle, help="largest random rotation, radians; also "
                   "'pi', 'pi/2', '0.5pi' or '90deg' (study's best: pi; 0 disables)")
    p.add_argument("--nodes-per-sample", type=_POS_INT, help="subsample N nodes per sample, clot "
                   "fraction kept (study: 2048 on ClotEntry; default all nodes)")
    p.add_argument("--bary-ratio", type=_NN_FLOAT, help="BaryCentricSampling samples per real "
                   "sample (study's best on BendVessel: 2, i.e. real:generated 1:2; default 0)")
    p.add_argument("--noise-std", type=_NN_FLOAT, help="training noise on s_t (default 0: off)")
    p.add_argument("--seed", type=_NN_INT, help="seed of initialisation, data order, augmentations")
    p.add_argument("--skip-frames", type=_NN_INT, help="first frames never used as frame t of a "
                   "window (default 0: every window)")
    p.add_argument("--rollout-steps", type=_POS_INT, help="k of the k-step unrolled loss "
                   "(default 1: single-step loss)")
    p.add_argument("--n-val", type=_NN_INT, help="validation simulations (default 2)")
    p.add_argument("--n-test", type=_NN_INT, help="test simulations, never trained on (default 1)")
    p.add_argument("--tiny", action="store_true", default=None, help="tiny model config")
    p.add_argument("--distributed", action="store_true",
                   help="multi-host: call jax.distributed.initialize() first (run on every host)")
    _output_flags(p, "start a new run in DIR even if it holds one (its checkpoints are removed)")
    p.set_defaults(func=_run_train)


def _run_train(args) -> int:
    from thrombojax.train.config import RunConfig, TrainConfig, load_config_file
    from thrombojax.train.loop import train

    names = ("epochs", "batch_size", "lr", "warmup_epochs", "max_rotation",
             "nodes_per_sample", "bary_ratio", "noise_std", "seed", "skip_frames", "n_val",
             "n_test", "tiny", "rollout_steps")
    overrides = {k: getattr(args, k) for k in names if getattr(args, k) is not None}
    config = load_config_file(args.config) if args.config else None
    if args.radius is not None:
        base = config.train if isinstance(config, RunConfig) else (config or TrainConfig())
        overrides["model_config"] = {**base.model_config, "radius": args.radius}
    from thrombojax.train.summary import run_summary

    trained = train(args.dataset, args.model, args.out, config=config, resume=args.resume,
                    progress=not args.quiet, distributed=args.distributed, force=args.force,
                    **overrides)
    print(run_summary(args.out, trained.model.name))
    return 0


_REGISTRARS += [_add_train]


# ---- evaluate, rollout, export, bench ---------------------------------------------------


def _add_evaluate(sub) -> None:
    p = sub.add_parser(
        "evaluate",
        help="single-step MSE of a trained run on its test split (JSON + markdown table)",
        description=(
            "Teacher-forced one-step prediction on every window of the run's test split: MSE over "
            "clot nodes in scaled [-1, 1] coordinates (the study's metric), beside the "
            "constant-velocity baseline. Writes evaluate.json and evaluate.md."
        ),
    )
    p.add_argument("--run", required=True, metavar="DIR", help="training run directory")
    p.add_argument("--dataset", required=True, metavar="FILE", help="dataset .h5 file")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the run directory)")
    p.add_argument("--split", default="test", choices=("train", "val", "test", "all"))
    p.add_argument("--checkpoint", default="best", choices=("best", "last"))
    p.add_argument("--skip", type=_NN_INT, default=0,
                   help="skip windows whose middle frame < SKIP")
    p.add_argument("--nodes", type=_POS_INT, help="fixed seeded node subset (default: the "
                   "run's nodes_per_sample, else all nodes)")
    _output_flags(p, "replace existing evaluate.json / evaluate.md")
    p.set_defaults(func=_run_evaluate)


def _run_evaluate(args) -> int:
    from thrombojax.eval.single_step import evaluate_run

    res = evaluate_run(args.run, args.dataset, out_dir=args.out, split=args.split,
                       which=args.checkpoint, skip=args.skip, n_nodes=args.nodes,
                       progress=not args.quiet, force=args.force)
    print(res["table"], end="")
    print(f"wrote {args.out or args.run}/evaluate.json and evaluate.md")
    return 0


def _add_rollout(sub) -> None:
    p = sub.add_parser(
        "rollout",
        help="roll a trained run out: trajectory HDF5, ParaView series, GIF, error plots",
        description=(
            "Autoregressive rollout (one compiled jax.lax.scan) of a trained run on dataset "
            "simulations, starting after the dataset's skipped frames (its skip_frames attribute: "
            "5 BendVessel, 40 ClotEntry, as in the study). "
            "Writes per simulation: <sim>_rollout.h5 (dataset schema), <sim>_prediction.xdmf and "
            "<sim>_truth.xdmf (node types and error as point data), <sim>_rollout.gif (prediction "
            "beside ground truth), <sim>_error.png and <sim>_metrics.png (with the "
            "constant-velocity baseline), plus rollout.json and rollout.md."
        ),
    )
    p.add_argument("--run", required=True, metavar="DIR", help="training run directory")
    p.add_argument("--dataset", required=True, metavar="FILE", help="dataset .h5 file")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--sim", action="append", metavar="NAME",
                   help="simulation to roll out (repeatable; default: the run's test split)")
    p.add_argument("--split", default="test", choices=("train", "val", "test", "all"))
    p.add_argument("--checkpoint", default="best", choices=("best", "last"))
    p.add_argument("--skip", type=_NN_INT, help="skipped frames (default: the dataset's "
                   "skip_frames attribute)")
    p.add_argument("--steps", type=_POS_INT, help="rollout steps (default: to the last frame)")
    p.add_argument("--nodes", type=_POS_INT, help="fixed seeded node subset (the study: 2048 on "
                   "ClotEntry; default: the run's nodes_per_sample, else all nodes)")
    p.add_argument("--seed", type=_NN_INT, default=0, help="seed of the node subset")
    p.add_argument("--format", default="xdmf", choices=("xdmf", "vtu"), help="ParaView format")
    p.add_argument("--no-gif", action="store_true", help="skip the animation")
    _output_flags(p, "replace existing rollout files in DIR")
    p.set_defaults(func=_run_rollout)


def _run_rollout(args) -> int:
    from thrombojax.eval.report import rollout_run

    res = rollout_run(args.run, args.dataset, args.out, simulations=args.sim, split=args.split,
                      which=args.checkpoint, skip=args.skip, n_steps=args.steps,
                      n_nodes=args.nodes, seed=args.seed, format=args.format,
                      gif=not args.no_gif, force=args.force, progress=not args.quiet)
    print(res["table"], end="")
    print(f"wrote rollouts to {args.out}/")
    return 0


def _add_export(sub) -> None:
    p = sub.add_parser(
        "export",
        help="export dataset simulations or saved rollouts to XDMF / VTU time series",
        description=(
            "Write a ParaView time series (moving points, node_type and displacement as point "
            "data, clot tetrahedra and wall triangles when present) for simulations of a "
            "dataset file or of a <sim>_rollout.h5 written by 'thrombojax rollout'."
        ),
    )
    p.add_argument("file", metavar="FILE", help="dataset or rollout .h5 file")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--sim", action="append", metavar="NAME",
                   help="simulation to export (repeatable; default: all)")
    p.add_argument("--format", default="xdmf", choices=("xdmf", "vtu"),
                   help="xdmf: .xdmf + .h5 (ParaView, VTK, meshio TimeSeriesReader); vtu: .pvd + "
                        "one .vtu per frame (every VTK reader, meshio.read per file)")
    _output_flags(p, "replace existing exported series")
    p.set_defaults(func=_run_export)


def _run_export(args) -> int:
    from thrombojax.io.export import export_file

    for path in export_file(args.file, args.out, names=args.sim, format=args.format,
                            force=args.force, progress=not args.quiet):
        print(f"wrote {path}")
    return 0


def _add_bench(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="time rollouts at the study's sizes; speed-up over Abaqus and our solver",
        description=(
            "For each model and size (bendvessel: 35 steps x 977 nodes; clotentry: 160 x 2048; "
            "clotentry-full: 160 x 27000) report compile time, steady-state rollout time, "
            "per-step time, the time scaled to the whole simulation and the speed-up over the "
            "study's Abaqus times (180 s / 1500 s) and our solver's measured time. Models are "
            "random-initialised (timing needs no trained weights) unless --run is given. "
            "Writes bench.json and bench.md with device, versions and date."
        ),
    )
    p.add_argument("--models", default="mgn,transolver,erwin", help="comma-separated models")
    p.add_argument("--cases", default="bendvessel,clotentry,clotentry-full",
                   help="comma-separated sizes: bendvessel, clotentry, clotentry-full")
    p.add_argument("--run", action="append", metavar="MODEL=DIR", default=[],
                   help="time a trained run for MODEL (repeatable)")
    p.add_argument("--tiny", action="store_true", help="tiny configs instead of the study's")
    p.add_argument("--nodes", type=_POS_INT, help="override every case's node count")
    p.add_argument("--max-steps", type=_POS_INT,
                   help="time at most this many steps; extrapolate")
    p.add_argument("--repeats", type=_POS_INT, default=3, help="steady-state repetitions (median)")
    p.add_argument("--dataset", metavar="FILE", help="take positions from this dataset")
    p.add_argument("--solver-dataset", action="append", default=[], metavar="FILE",
                   help="dataset whose solver_wall_time_s is our solver's time (repeatable)")
    p.add_argument("--measure-solver", action="append", default=[], metavar="PRESET",
                   help="run this solver preset once now to time our solver (repeatable)")
    p.add_argument("--out", metavar="DIR", help="write bench.json and bench.md here")
    _output_flags(p, "replace existing bench.json / bench.md")
    p.set_defaults(func=_run_bench)


def _run_bench(args) -> int:
    from thrombojax.errors import ConfigError
    from thrombojax.eval.bench import bench

    runs = {}
    for item in args.run:
        if "=" not in item:
            raise ConfigError(f"--run expects MODEL=DIR, got '{item}'")
        name, path = item.split("=", 1)
        runs[name] = path
    res = bench(tuple(m for m in args.models.split(",") if m),
                tuple(c for c in args.cases.split(",") if c), runs=runs, tiny=args.tiny,
                n_nodes=args.nodes, max_steps=args.max_steps, repeats=args.repeats,
                dataset=args.dataset, solver_datasets=tuple(args.solver_dataset),
                measure_solver=tuple(args.measure_solver), out_dir=args.out,
                progress=not args.quiet, force=args.force)
    print(res["table"], end="")
    for path in res.get("files", []):
        print(f"wrote {path}")
    return 0


_REGISTRARS += [_add_evaluate, _add_rollout, _add_export, _add_bench]


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``thrombojax generate: error: argument --sims: ...``."""

    def error(self, message: str):
        print(f"{self.prog}: error: {' '.join(message.split())} (see '{self.prog} --help')",
              file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser with every working subcommand."""
    parser = _Parser(
        prog="thrombojax",
        description=(
            "Learned step-by-step surrogates of mechanical-thrombectomy simulations: "
            "generate or import datasets, train MeshGraphNet / Transolver / Erwin, "
            "roll them out and benchmark them."
        ),
    )
    from thrombojax import __version__

    parser.add_argument("--version", action="version", version=f"thrombojax {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for register in _REGISTRARS:
        register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``thrombojax`` console script. Returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning(args.command)
            result = args.func(args)
        sys.stdout.flush()
    except BrokenPipeError:  # `thrombojax info X | head`: the reader has gone, nothing to say
        _silence_stdout()
        return 0
    except (ThrombojaxError, OSError) as err:  # OSError: missing, unreadable, read-only paths
        text = " ".join(str(err).split())
        print(f"thrombojax {args.command}: error: {text}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"thrombojax {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(result or 0)


def _one_line_warning(command: str):
    """Print warnings as ``thrombojax COMMAND: warning: ...`` (one line, no source excerpt)."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"thrombojax {command}: warning: {' '.join(str(message).split())}",
              file=sys.stderr)
    return show


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush raises no second error."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


if __name__ == "__main__":
    sys.exit(main())
