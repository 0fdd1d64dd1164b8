"""Subcommands that read and write dataset files: ``info``, ``import``, ``generate``, ``export``."""

from __future__ import annotations

from thrombojax.cli.options import (
    NN_INT,
    POS_FLOAT,
    POS_INT,
    output_flags,
)

__all__ = ["REGISTRARS"]


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
    p.add_argument("--dt", type=POS_FLOAT, help="time step between stored frames, stored "
                   "per sim")
    p.add_argument("--reference-time", type=POS_FLOAT, metavar="SECONDS",
                   help="recorded solver wall time per simulation (e.g. Abaqus), for speed-ups")
    p.add_argument("--units", required=True, metavar="UNIT",
                   help="length unit of the coordinates, e.g. mm, m or 'vessel radius' "
                        "(stored in the dataset, shown in every report and picture)")
    p.add_argument("--kind", default="unknown", choices=("bendvessel", "clotentry", "unknown"),
                   help="which of the study's datasets this is like (default unknown)")
    p.add_argument("--skip-frames", type=NN_INT, default=0, help="leading frames rollouts skip "
                   "(the clot still entering; the study: 5 BendVessel, 40 ClotEntry; default 0)")
    output_flags(p, "overwrite FILE if it exists")


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
        kind=args.kind, skip_frames=args.skip_frames,
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
        kind=args.kind, skip_frames=args.skip_frames,
        progress=not args.quiet,
    )
    print(f"wrote {out}")
    return 0


def _add_generate(sub) -> None:
    p = sub.add_parser(
        "generate",
        help="run the built-in solver and write a dataset",
        description=(
            "Simulate a clot driven through a rigid vessel (explicit FEM in JAX) for every "
            "simulation of a preset and write the HDF5 dataset. Presets: bendvessel (20 rotated "
            "bent tubes, 41 frames), bendvessel-shapes (20 bent tubes, each with its own outlet "
            "leg, bend radius and angle, 41 frames), clotentry (10 tortuous vessels, 201 "
            "frames), bendvessel-tiny, clotentry-tiny (for tests)."
        ),
    )
    p.add_argument("preset", help="bendvessel | bendvessel-shapes | clotentry | bendvessel-tiny | "
                   "clotentry-tiny")
    p.add_argument("--out", required=True, help="output .h5 file")
    p.add_argument("--sims", type=POS_INT, default=None,
                   help="number of simulations (default: all)")
    p.add_argument("--seed", type=NN_INT, default=0, help="dataset seed (same seed, same arrays)")
    p.add_argument("--plot", action="store_true",
                   help="also write a picture of the first simulation (bv.h5 -> bv.png)")
    output_flags(p, "replace an existing output file")
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
    output_flags(p, "replace existing exported series")
    p.set_defaults(func=_run_export)


def _run_export(args) -> int:
    from thrombojax.io.export import export_file

    for path in export_file(args.file, args.out, names=args.sim, format=args.format,
                            force=args.force, progress=not args.quiet):
        print(f"wrote {path}")
    return 0


REGISTRARS = [_add_info, _add_import, _add_generate, _add_export]
