"""The ``thrombojax rollout`` command: roll a trained run out and write everything a user opens.

For each chosen simulation, into ``out_dir``:

- ``<sim>_rollout.h5``: the predicted trajectory in the dataset schema (physical units; frames
  s_{t0-1}, s_{t0}, then the predictions), so every dataset tool (``thrombojax info``,
  ``thrombojax export``) reads it;
- ``<sim>_prediction.xdmf`` / ``<sim>_truth.xdmf`` (+ ``.xdmf.h5``): ParaView time series with
  ``node_type`` and the per-node ``error`` (distance to the truth) as point data, at the
  physical times ``frame * dt`` (so they play in step with an exported dataset simulation);
- ``<sim>_rollout.gif``: prediction beside ground truth, equal axes, clot coloured by error;
- ``<sim>_summary.png``: the model, constant velocity and the truth side by side at 4 frames;
- ``<sim>_error.png`` (MSE per step) and ``<sim>_metrics.png`` (MSE, centroid error, fraction
  outside the vessel), always with the constant-velocity baseline;
- ``rollout.json`` (all metrics and curves) and ``rollout.md`` (:mod:`thrombojax.eval.
  truth_tables`): every error in scaled units and in vessel radii (the conversion recorded,
  :mod:`thrombojax.eval.physical`), beside constant velocity with the ratio model / CV, and the
  teacher-forced single-step MSE on the same nodes by phase (:mod:`thrombojax.eval.phases`).

Any dataset in the run's length unit can be rolled out: by default the run's test split on its
own dataset, every simulation of another (:func:`thrombojax.eval.single_step.select_simulations`).

``<sim>`` is :func:`thrombojax.io.outputs.safe_stems` of the simulation name. Every file is
written atomically; existing files are replaced only with ``force=True`` (all targets are
checked before the first rollout runs).
"""

from __future__ import annotations

import json
import pathlib
import warnings

import numpy as np
from tqdm.auto import tqdm

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.data.scaling import Scaling
from thrombojax.errors import ConfigError, DatasetError
from thrombojax.eval.centring_fit import fit_centring
from thrombojax.eval.coherence_fit import fit_coherence
from thrombojax.eval.phases import PHASE_HELP
from thrombojax.eval.physical import curves_in_radii, radius_units, summary_in_radii
from thrombojax.eval.plots import animate_rollout, plot_error_curves, plot_rollout_metrics
from thrombojax.eval.rollout_pull import rollout_pull, training_dataset_of
from thrombojax.eval.rollouts import RolloutResult, rollout_simulation
from thrombojax.eval.single_step import (
    scaled_simulation,
    select_simulations,
    simulation_exit_frame,
    single_step_by_phase,
)
from thrombojax.eval.summary_plot import default_summary_frames, plot_rollout_summary
from thrombojax.eval.tables import environment
from thrombojax.eval.truth_tables import rollout_markdown
from thrombojax.io.export import export_trajectory
from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset
from thrombojax.io.outputs import atomic_path, atomic_write_text, check_targets, safe_stems
from thrombojax.simulator.guard_set import FIXED_COHERENCE_R
from thrombojax.simulator.rotations import RotatedStep, rotated_params, rotation_members
from thrombojax.train.ensemble import load_ensemble
from thrombojax.train.guards import check_finite, check_in_box
from thrombojax.train.state import load_trained
from thrombojax.units import check_units

__all__ = ["subset_cells", "rollout_files", "save_rollout", "rollout_run"]


def rollout_files(out_dir: pathlib.Path, stem: str, format: str, gif: bool) -> list[pathlib.Path]:
    """Every path :func:`save_rollout` writes for one simulation file stem."""
    series = (".xdmf", ".xdmf.h5") if format == "xdmf" else (".pvd", "")
    names = [f"{stem}_rollout.h5", f"{stem}_error.png", f"{stem}_metrics.png",
             f"{stem}_summary.png"]
    names += [f"{stem}_{kind}{ext}" for kind in ("prediction", "truth") for ext in series]
    return [out_dir / n for n in names + ([f"{stem}_rollout.gif"] if gif else [])]


def subset_cells(cells: np.ndarray | None, node_index: np.ndarray, n_nodes: int):
    """Cells whose every node is kept, re-indexed into the subset (``None`` if none remain)."""
    if cells is None:
        return None
    new = np.full(n_nodes, -1, np.int64)
    new[node_index] = np.arange(node_index.size)
    mapped = new[np.asarray(cells)]
    kept = mapped[(mapped >= 0).all(axis=1)].astype(np.int32)
    return kept if kept.size else None


def save_rollout(
    result: RolloutResult,
    sim: Simulation,
    scaling: Scaling,
    out_dir: pathlib.Path,
    *,
    model_name: str,
    format: str = "xdmf",
    gif: bool = True,
    stem: str | None = None,
    units: str = "",
) -> dict[str, str]:
    """Write the files of one rollout (see the module docstring); returns label -> path.

    ``units``: the dataset's length unit (axis labels and colour bars of the pictures).

    ``stem`` is the file-name stem (default: the simulation's safe stem); files are replaced.
    """
    n_all = sim.positions.shape[1]
    idx = result.node_index

    def phys(x):
        return np.asarray(scaling.invert(np.asarray(x, np.float32)), np.float32)

    pred = phys(np.concatenate([result.initial, result.pred]))
    true = phys(np.concatenate([result.initial, result.true]))
    clot_cells = subset_cells(sim.clot_cells, idx, n_all)
    wall_cells = subset_cells(sim.wall_cells, idx, n_all)
    dt = float(sim.attrs.get("dt", 1.0))
    stem = out_dir / (stem or safe_stems([result.name])[result.name])
    attrs = {"dt": dt, "source_simulation": sim.name, "model": model_name, "t0": result.t0,
             "first_frame": result.t0 - 1,
             "n_nodes_full": n_all, "subset": bool(idx.size < n_all)}
    for key in ("rotation_deg", "seed", "reference_wall_time_s", "solver_wall_time_s"):
        if key in sim.attrs:
            attrs[key] = sim.attrs[key]
    rollout_sim = Simulation(name=f"{result.name}_rollout", positions=pred,
                             node_type=result.node_type.astype(np.int8), clot_cells=clot_cells,
                             wall_cells=wall_cells, attrs=attrs)
    files = {"trajectory": write_dataset(stem.with_name(f"{stem.name}_rollout.h5"),
                                         [rollout_sim], name=f"{result.name} rollout",
                                         source=f"thrombojax rollout ({model_name})")}
    error = np.linalg.norm(pred - true, axis=-1)
    common = dict(clot_cells=clot_cells, wall_cells=wall_cells, dt=dt, format=format,
                  first_frame=result.t0 - 1)
    files["prediction"] = export_trajectory(stem.with_name(f"{stem.name}_prediction"), pred,
                                            result.node_type, point_data={"error": error},
                                            **common)
    files["truth"] = export_trajectory(stem.with_name(f"{stem.name}_truth"), true,
                                       result.node_type, **common)
    with atomic_path(stem.with_name(f"{stem.name}_error.png")) as tmp:
        plot_error_curves(
            {label: c["mse"] for label, c in result.curves.items() if "mse" in c}, tmp,
            title=f"{model_name} rollout on {result.name} from frame {result.t0}")
    files["error_png"] = stem.with_name(f"{stem.name}_error.png")
    with atomic_path(stem.with_name(f"{stem.name}_metrics.png")) as tmp:
        plot_rollout_metrics(
            result.curves, tmp,
            title=f"{model_name} rollout on {result.name} (from frame {result.t0}, "
                  f"{idx.size} nodes)")
    files["metrics_png"] = stem.with_name(f"{stem.name}_metrics.png")
    if gif:
        with atomic_path(stem.with_name(f"{stem.name}_rollout.gif")) as tmp:
            animate_rollout(pred, true, result.node_type, tmp,
                            title=f"{model_name} / {result.name}", first_frame=result.t0 - 1,
                            dt=dt, units=units)
        files["gif"] = stem.with_name(f"{stem.name}_rollout.gif")
    const = phys(np.concatenate([result.initial, result.baseline]))
    files["summary_png"] = plot_rollout_summary(
        true, pred, const, result.node_type, stem.with_name(f"{stem.name}_summary.png"),
        dt=dt, units=units, first_frame=result.t0 - 1,
        frames=1 + default_summary_frames(len(pred) - 1),  # from the given frame s_t0 on
        labels=(model_name, "constant velocity", "ground truth"),
        title=f"{model_name} rollout on {result.name}")
    return {k: str(v) for k, v in files.items()}


def rollout_run(
    run_dir: str | pathlib.Path,
    dataset_path: str | pathlib.Path,
    out_dir: str | pathlib.Path,
    *,
    simulations: list[str] | None = None,
    split: str | None = None,
    which: str = "best",
    skip: int | None = None,
    n_steps: int | None = None,
    n_nodes: int | None = None,
    seed: int = 0,
    format: str = "xdmf",
    gif: bool = True,
    force: bool = False,
    progress: bool = False,
    guards: bool = True,
    rotations: int = 0,
    centring_r: float | str | None = None,
    coherence_r: float | str | None = None,
    coherence_stretch: float | None = None,
    keep_wall_velocity: bool = False,
    centre_pull: float | None = None,
    centre_tolerance: float | str | None = None,
) -> dict:
    """Roll a trained run out on simulations of a dataset and write trajectories, plots, metrics.

    ``run_dir`` may also be an ensemble folder (``thrombojax.train.ensemble``, with
    ``ensemble.json``): the members roll out in one compiled program, the prediction is their
    mean and the per-step spread is reported beside the error.

    Args:
        run_dir: training run directory. dataset_path: any dataset file in the run's length
            unit. out_dir: output folder.
        simulations: names to roll out (``--sim``).
        split: ``train`` / ``val`` / ``test`` / ``all``; default (``None``): the run's test split
            on its own dataset, every simulation of another dataset
            (:func:`thrombojax.eval.single_step.select_simulations`).
        which: checkpoint, ``"best"`` or ``"last"``.
        skip: skipped frames; the rollout starts at frame ``max(skip, 1)`` (default: the
            dataset's ``skip_frames`` attribute, :func:`thrombojax.study.skip_frames`).
        n_steps: predicted frames (default: to the end).
        n_nodes: fixed seeded node subset size (default: the run's ``nodes_per_sample``, the
            density it was trained on, else all nodes).
        seed: subset seed. format: ``"xdmf"`` or ``"vtu"``. gif: write the animation.
        force: replace existing files in ``out_dir`` (never the dataset or the run).
        progress: progress bar over simulations.
        guards: apply the physics guards (containment in the vessel, clot coherence) after every
            step and report how far they moved nodes (False: the model alone).
        rotations: > 0: a rotation ensemble (:mod:`thrombojax.simulator.rotations`): every
            model (each member of an ensemble) rolls out on that many copies of each
            simulation, turned by ``fixed_rotations(rotations)`` (the first unturned) and
            turned back; the prediction is the mean of them all and the spread is reported as
            for an ensemble.
            The single-step table stays that of the model(s) unturned.
        centring_r: with the guards, also the centring guard: the whole clot moved rigidly to
            within this many vessel radii of the middle of the vessel's cross-section
            (:mod:`thrombojax.simulator.centring`; ``None``: off). ``"auto"``: the tolerance
            that leaves 95 % of the true clots' frames of the run's training simulations alone
            (:func:`thrombojax.eval.centring_fit.fit_centring` on the run's own dataset),
            recorded under ``centring_fit``.
        coherence_r: with the guards, the coherence guard's tolerance in vessel radii
            (recorded as ``coherence_r``). ``"auto"``: the tolerance that leaves 95 % of the
            true clots' (node, frame) pairs of the run's training simulations alone
            (:func:`thrombojax.eval.coherence_fit.fit_coherence` on the run's own dataset),
            recorded under ``coherence_fit``; an error when that dataset is not there.
            ``None`` (the default): ``"auto"`` when the run's dataset is there, else the fixed
            ``FIXED_COHERENCE_R`` (1 r) with a warning.
        coherence_stretch: with the guards, the coherence guard's copy of the start frame may
            stretch, without a change of volume, up to this principal stretch (>= 1;
            :func:`thrombojax.simulator.guards.coherence`'s ``max_stretch``; ``None``, the
            default: a rigid copy); ``"auto"`` then fits the tolerance to that copy.
        keep_wall_velocity: with the guards, the step after containment reads the velocity
            from before it (``build_guards``' ``keep_velocity_wall``; recorded).
        centre_pull: the vessel-following prior's centring pull at this strength in (0, 1]
            (a run trained with ``--follow-axis``), at rollout time, in the single steps too
            (:mod:`thrombojax.eval.rollout_pull`); ``None``: the run's own (trained) pull.
        centre_tolerance: its tolerance in vessel radii, or ``"auto"`` (the default): the
            median offset of the run's training clots from the vessel's middle; recorded with
            the fit under ``centre_pull``.
    Returns:
        JSON-ready summary (also written to ``rollout.json``; tables in ``rollout.md``, the one
        in vessel radii under ``table``).
    """
    if centring_r is not None and not guards:
        raise ConfigError("rollout: centring is a guard; it cannot run without the guards "
                          "(--centring with --no-guards)")
    for value, what, flag in ((coherence_r, "tolerance", "--coherence-tolerance"),
                              (coherence_stretch, "stretch", "--coherence-stretch")):
        if value is not None and not guards:
            raise ConfigError(f"rollout: the coherence {what} is a guard's; it cannot run "
                              f"without the guards ({flag} with --no-guards)")
    if keep_wall_velocity and not guards:
        raise ConfigError("rollout: the velocity kept through containment is a guard's; it "
                          "cannot run without the guards (--keep-wall-velocity with --no-guards)")
    ensemble = (pathlib.Path(run_dir) / "ensemble.json").is_file()
    if ensemble:
        members = load_ensemble(run_dir, which=which)
        trained, params = members.members[0], members.params
    else:
        trained = load_trained(run_dir, which=which)
        params = trained.params
    n_members = members.n_members if ensemble else 1
    if rotations:  # each model on each turned copy: one member per (model, rotation)
        params = (rotation_members(params, rotations) if ensemble
                  else rotated_params(params, rotations))
        n_members *= int(rotations)
    ds = open_dataset(dataset_path)
    check_units(trained.config, ds, run_dir=run_dir, dataset_path=dataset_path)
    names, how = select_simulations(trained, ds, simulations=simulations, split=split,
                                   dataset_path=dataset_path, run_dir=run_dir)
    skip_frames = study.skip_frames(ds)
    skip = skip_frames if skip is None else int(skip)
    n_nodes = n_nodes or trained.run.train.nodes_per_sample
    out_dir = pathlib.Path(out_dir)
    stems = safe_stems(names)
    targets = [f for n in names for f in rollout_files(out_dir, stems[n], format, gif)]
    check_targets([*targets, out_dir / "rollout.json", out_dir / "rollout.md"],
                  inputs=(dataset_path,), force=force, what="rollout output")
    centring_fit = None
    if centring_r == "auto":
        centring_fit = _auto_centring(trained, ds, dataset_path, run_dir)
        centring_r = centring_fit["centring_r"]
    coherence_fit = None
    if guards and coherence_r in (None, "auto"):
        coherence_fit = _auto_coherence(trained, ds, dataset_path, run_dir,
                                        required=coherence_r == "auto",
                                        max_stretch=coherence_stretch)
        coherence_r = coherence_fit["coherence_r"] if coherence_fit else FIXED_COHERENCE_R
    units = radius_units(trained.scaling, ds)
    base, pull = rollout_pull(
        trained.step, trained, lambda: training_dataset_of(
            trained, ds, dataset_path, run_dir, "--centre-tolerance"),
        strength=centre_pull, tolerance=centre_tolerance, radius=1.0 / units.factor,
        run_dir=run_dir)
    step = RotatedStep.of(base) if rotations else base
    out_dir.mkdir(parents=True, exist_ok=True)
    report = {}
    for name in tqdm(names, desc=f"rollout {trained.model.name}", unit="sim",
                     disable=not progress):
        sim = ds[name]
        pos, node_type = scaled_simulation(ds, name, trained.scaling)
        check_in_box(pos, name, dataset_path, run_dir)
        res = rollout_simulation(step, params, trained.stats, pos, node_type,
                                 name=name, t0=max(skip, 1), n_steps=n_steps, n_nodes=n_nodes,
                                 seed=seed, wall_cells=sim.wall_cells,
                                 ensemble=n_members > 1 or bool(rotations),
                                 guard_radius=1.0 / units.factor if guards else None,
                                 centring_r=centring_r, coherence_r=coherence_r,
                                 coherence_stretch=coherence_stretch,
                                 keep_wall_velocity=keep_wall_velocity)
        check_finite({"predicted positions": float(np.sum(res.pred))},
                     f"{run_dir}: checkpoint '{which}' on simulation '{name}'")
        exit_at = simulation_exit_frame(pos, node_type, sim.wall_cells)
        _, single = single_step_by_phase(
            base, trained.params, trained.stats, pos[:, res.node_index], res.node_type,
            skip_frames=skip_frames, exit_at=exit_at, units=units)
        files = save_rollout(res, sim, trained.scaling, out_dir, model_name=trained.model.name,
                             format=format, gif=gif, stem=stems[name],
                             units=str(ds.attrs.get("units", "")))
        report[name] = {"t0": res.t0, "n_steps": int(res.pred.shape[0]),
                        "n_nodes": int(res.node_index.size), "exit_frame": exit_at,
                        "summary": summary_in_radii(res.summary, units),
                        "single_step": single, "files": files,
                        "node_index": res.node_index.tolist(),
                        "curves": curves_in_radii(res.curves, units)}
    env = environment()  # device, versions, command and load, beside the figures
    result = {"model": trained.model.name, "run_dir": str(run_dir), "dataset": str(dataset_path),
              "selection": {"how": how, "simulations": names}, "skip": skip,
              "skip_frames": skip_frames, "seed": seed, "units": units.to_dict(),
              "guards": bool(guards), "centring_r": centring_r, "centring_fit": centring_fit,
              "coherence_r": coherence_r, "coherence_fit": coherence_fit,
              "coherence_stretch": coherence_stretch,
              "keep_wall_velocity": bool(keep_wall_velocity), "centre_pull": pull,
              "checkpoint": which, "ensemble_members": n_members, "rotations": int(rotations),
              "phase_definitions": PHASE_HELP, "date": env["date"], "environment": env,
              "simulations": report}
    atomic_write_text(out_dir / "rollout.json", json.dumps(result, indent=1))
    markdown, table = rollout_markdown(result)
    atomic_write_text(out_dir / "rollout.md", markdown)
    result["table"] = table
    return result


def _auto_centring(trained, ds, dataset_path, run_dir) -> dict:
    """``--centring auto``: fit the tolerance on the run's training simulations."""
    train_ds = training_dataset_of(trained, ds, dataset_path, run_dir, "--centring")
    return fit_centring(train_ds, trained.split.train, float(vessel_radius(train_ds)))


def _auto_coherence(trained, ds, dataset_path, run_dir, *, required: bool,
                    max_stretch: float | None = None) -> dict | None:
    """``--coherence-tolerance auto`` (``required``) or the default: fit the tolerance on the
    run's training simulations, from their dataset's rollout start (``skip_frames``), for the
    guard's copy (rigid, or stretching up to ``max_stretch``). As the
    default, a run whose dataset is not there (or cannot be fitted) keeps the fixed tolerance
    (None returned) with a warning that says why."""
    try:
        train_ds = training_dataset_of(trained, ds, dataset_path, run_dir, "--coherence-tolerance")
        return fit_coherence(train_ds, trained.split.train, float(vessel_radius(train_ds)),
                             study.skip_frames(train_ds), max_stretch=max_stretch)
    except (ConfigError, DatasetError) as err:
        if required:
            raise
        warnings.warn(f"the coherence tolerance was not fitted ({err}); the coherence guard "
                      f"keeps the fixed tolerance of {FIXED_COHERENCE_R:g} r", stacklevel=3)
        return None
