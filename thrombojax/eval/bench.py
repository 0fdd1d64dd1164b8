"""Rollout speed: compile time, steady-state time, per-step time and speed-up over the solvers.

The study's setting (:data:`thrombojax.study.DATASETS`): BendVessel 35 rollout steps x 977 nodes
(Abaqus 180 s per simulation), ClotEntry 160 steps x 2,048 nodes (Abaqus 1500 s); we add
ClotEntry at full resolution (~27,000 nodes). As in the study, rollout times are scaled to the
full simulation length (x 40/35 and x 200/160) before the speed-up is computed, because the solver
time covers every frame. Speed-up over our own solver uses its measured ``solver_wall_time_s`` on
the same machine (read from a dataset, or measured by running a preset).

Timing does not need trained weights: the cost of a rollout depends on the architecture and
the shapes only, so models are random-initialised from their study configs unless trained runs
are given. Positions come from a dataset frame when one is given, else from a synthetic bent
tube with a clot (same node counts, scaled [-1, 1]); the radius graphs are capped at
``max_neighbors`` either way. Where the cell grid pays (full resolution), the radius graphs are
built on it: its :class:`~thrombojax.graph.grid.GridSpec` is sized from the two given frames
(:func:`thrombojax.simulator.grid_step.allocate_grid`) and grown and recompiled if the timed
rollout overflows (``graph`` and ``grid`` in each result say which search ran). Compile time is
measured with ``jit(...).lower(...).compile()``; steady-state time is the median of ``repeats``
runs of the compiled rollout (synchronised with ``block_until_ready``). The persistent
compilation cache is switched off while compiling, so the compile time is a real compilation,
not a cache read.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import statistics
import time

import jax
import numpy as np
from tqdm.auto import tqdm

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.scaling import fit_scaling
from thrombojax.errors import ConfigError
from thrombojax.eval.single_step import scaled_simulation
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.models.registry import (
    Surrogate,
    config_to_dict,
    create_model,
    get_config,
    identity_stats,
)
from thrombojax.sim.generate import simulate
from thrombojax.sim.presets import get_preset
from thrombojax.simulator.grid_step import allocate_grid, run_checked
from thrombojax.simulator.rollout import as_step, rollout_jit
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.train.guards import warn_large_cpu_cases
from thrombojax.train.state import load_trained
from thrombojax.types import NodeType, TargetStats

__all__ = [
    "BenchCase",
    "STUDY_CASES",
    "synthetic_cloud",
    "time_rollout",
    "bench",
    "bench_markdown",
    "run_config_label",
]


@dataclasses.dataclass(frozen=True)
class BenchCase:
    """One benchmark size.

    Attributes:
        name: case name. n_nodes: nodes rolled out. n_steps: rollout steps (study's length).
        full_frames: frames of the whole simulation (the scaling to full length).
        abaqus_s: the study's recorded Abaqus wall time per simulation.
        kind: which dataset / solver preset the case belongs to.
    """

    name: str
    n_nodes: int
    n_steps: int
    full_frames: int
    abaqus_s: float
    kind: str


def _study_cases() -> dict[str, BenchCase]:
    bv, ce = study.DATASETS["bendvessel"], study.DATASETS["clotentry"]
    return {
        "bendvessel": BenchCase("bendvessel", bv.rollout_nodes, bv.rollout_steps, bv.n_frames,
                                bv.abaqus_s, "bendvessel"),
        "clotentry": BenchCase("clotentry", ce.rollout_nodes, ce.rollout_steps, ce.n_frames,
                               ce.abaqus_s, "clotentry"),
        "clotentry-full": BenchCase("clotentry-full", ce.n_nodes, ce.rollout_steps, ce.n_frames,
                                    ce.abaqus_s, "clotentry"),
    }


STUDY_CASES: dict[str, BenchCase] = _study_cases()
"""The study's rollout sizes (from :data:`thrombojax.study.DATASETS`) plus ClotEntry at full
resolution."""


def synthetic_cloud(n_nodes: int, *, clot_fraction: float = 0.3, seed: int = 0):
    """A bent tube wall with a clot inside, in scaled coordinates.

    Args:
        n_nodes: total nodes. clot_fraction: share of clot nodes. seed: RNG seed.
    Returns:
        ``(x_prev [n, 3], x_cur [n, 3], node_type [n])`` float32 / int32; the clot moves by a
        small step along the tube.
    """
    rng = np.random.default_rng(seed)
    n_clot = max(1, int(round(n_nodes * clot_fraction)))
    n_wall = n_nodes - n_clot
    radius, bend = 0.18, 0.8

    def tube(s, rho, phi):  # s in [0, 1] along a 90 deg arc of radius `bend`
        th = s * np.pi / 2
        c = np.stack([bend * np.sin(th), bend * (1 - np.cos(th)), 0 * th], -1)
        e_r = np.stack([np.sin(th), -np.cos(th), 0 * th], -1)
        e_z = np.array([0.0, 0.0, 1.0])
        return c + rho[:, None] * (np.cos(phi)[:, None] * e_r + np.sin(phi)[:, None] * e_z)

    wall = tube(rng.uniform(0, 1, n_wall), np.full(n_wall, radius), rng.uniform(0, 6.3, n_wall))
    s = rng.uniform(0.4, 0.6, n_clot)
    rho, phi = radius * 0.7 * np.sqrt(rng.uniform(0, 1, n_clot)), rng.uniform(0, 6.3, n_clot)
    x_cur = np.concatenate([tube(s, rho, phi), wall]) - [bend / 2, bend / 2, 0]
    x_prev = x_cur.copy()
    x_prev[:n_clot] = tube(s - 0.002, rho, phi) - [bend / 2, bend / 2, 0]
    node_type = np.array([NodeType.CLOT] * n_clot + [NodeType.VESSEL] * n_wall, np.int32)
    return x_prev.astype(np.float32), x_cur.astype(np.float32), node_type


def time_rollout(model: Surrogate | LearnedStep, params: dict, stats: TargetStats, x_prev, x_cur,
                 node_type, n_steps: int, *, repeats: int = 3, grid: bool = True) -> dict:
    """Compile and time one rollout shape (the compiled rollout of the learned step).

    With ``grid`` the step's radius graphs use the cell grid where it pays (module docstring);
    a grid that overflows is grown and the rollout recompiled (the last compilation is timed).

    Returns:
        ``{"compile_s", "rollout_s" (median steady state), "rollout_min_s", "per_step_s",
        "finite", "graph" ("grid" or "dense"), "grid" (the GridSpec or None)}``.
    """
    step = as_step(model)
    args = (params, stats, np.asarray(x_prev, np.float32), np.asarray(x_cur, np.float32),
            np.asarray(node_type, np.int32), np.ones(len(node_type), bool))
    if grid and step.grid is None:
        frames = np.concatenate([np.reshape(args[2], (-1, *args[3].shape)), args[3][None]])
        step = allocate_grid(step, frames, args[4])

    def compile_and_run(s):
        t = time.perf_counter()
        compiled = rollout_jit.lower(s, *args, n_steps=int(n_steps)).compile()
        compile_s = time.perf_counter() - t
        traj, _, overflow = compiled(*args)
        jax.block_until_ready(traj)  # warm-up run (allocations), not timed
        return (compiled, compile_s, traj), overflow

    enabled = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)  # time a real compilation
    try:
        (compiled, compile_s, traj), step = run_checked(compile_and_run, step,
                                                        what="bench rollout")
    finally:
        jax.config.update("jax_enable_compilation_cache", enabled)
    times = []
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t)
    med = statistics.median(times)
    return {"compile_s": compile_s, "rollout_s": med, "rollout_min_s": min(times),
            "per_step_s": med / n_steps, "finite": bool(np.isfinite(np.asarray(traj)).all()),
            "graph": "dense" if step.grid is None else "grid",
            "grid": None if step.grid is None else str(step.grid)}


def _solver_times(datasets: list, measure_presets: list[str]) -> dict[str, float]:
    """Mean measured solver wall time per simulation, keyed by kind (bendvessel / clotentry)."""
    out: dict[str, float] = {}
    for path in datasets:
        ds = open_dataset(path)
        vals = [float(ds.sim_attrs(n)["solver_wall_time_s"]) for n in ds.names
                if "solver_wall_time_s" in ds.sim_attrs(n)]
        if vals:
            out[study.dataset_kind(ds)] = float(np.mean(vals))
    for name in measure_presets:
        preset = get_preset(name)
        t = time.perf_counter()
        sim = simulate(preset, 0)
        out[preset.study] = float(sim.attrs.get("solver_wall_time_s",
                                                        time.perf_counter() - t))
    return out


def _inputs(case: BenchCase, dataset, seed: int, step: LearnedStep):
    """``((x_prev, x_cur, node_type), source)``, ``x_prev`` in the shape ``step`` reads
    (:meth:`LearnedStep.previous`; the synthetic tube extends its velocity backwards)."""
    if dataset is None:
        x_prev, x_cur, node_type = synthetic_cloud(case.n_nodes, seed=seed)
        v = x_cur - x_prev
        frames = np.stack([x_cur - (step.history - j) * v for j in range(step.history + 1)])
        return (step.previous(frames, step.history), x_cur, node_type), "synthetic bent tube"
    name = dataset.names[0]
    pos, node_type = scaled_simulation(dataset, name, fit_scaling(dataset))
    t0 = min(max(study.skip_frames(dataset), 1), pos.shape[0] - 1)
    idx = subsample_indices(seed, node_type, case.n_nodes)
    x_prev = step.previous(pos, t0)[..., idx, :]
    return (x_prev, pos[t0, idx], node_type[idx]), f"{dataset.path}:{name}"


def bench(
    models: tuple[str, ...] = ("mgn", "transolver", "erwin"),
    cases: tuple[str, ...] = ("bendvessel", "clotentry", "clotentry-full"),
    *,
    runs: dict[str, str] | None = None,
    tiny: bool = False,
    n_nodes: int | None = None,
    max_steps: int | None = None,
    repeats: int = 3,
    dataset: str | None = None,
    solver_datasets: tuple[str, ...] = (),
    measure_solver: tuple[str, ...] = (),
    out_dir: str | pathlib.Path | None = None,
    seed: int = 0,
    progress: bool = True,
    force: bool = False,
) -> dict:
    """Time rollouts of each model at each case size and compare with the solvers.

    Args:
        models: registry names. cases: keys of :data:`STUDY_CASES`.
        runs: model name -> trained run directory (its model, config and params are used).
        tiny: random-initialise the tiny configs instead of the study configs.
        n_nodes: override every case's node count. max_steps: time at most this many steps
            and extrapolate per-step time to the case length (reported as ``extrapolated``).
        repeats: steady-state repetitions (median reported).
        dataset: take positions from this dataset instead of the synthetic tube.
        solver_datasets: datasets whose ``solver_wall_time_s`` is our solver's time.
        measure_solver: presets to run once now to measure our solver's time.
        out_dir: write ``bench.json`` and ``bench.md`` there. seed: init / subset seed.
        progress: show a progress bar.
        force: replace an existing ``bench.json`` / ``bench.md`` (checked before timing).
    Returns:
        JSON-ready ``{"environment", "note", "results": [...]}`` (plus ``"files"`` when
        ``out_dir`` is given).
    """
    unknown = [c for c in cases if c not in STUDY_CASES]
    if unknown:
        raise ConfigError(f"unknown bench case(s) {unknown}; known: {list(STUDY_CASES)}")
    if out_dir is not None:
        check_targets([pathlib.Path(out_dir) / "bench.json", pathlib.Path(out_dir) / "bench.md"],
                      force=force, what="benchmark result")
    warn_large_cpu_cases(cases, n_nodes, STUDY_CASES)
    runs = dict(runs or {})
    ds = None
    if dataset is not None:
        ds = open_dataset(dataset)
        ds.validate()  # the values `thrombojax info` checks
    solver = _solver_times(list(solver_datasets), list(measure_solver))
    results, inits = [], {}
    jobs = [(m, c) for m in models for c in cases]
    for model_name, case_name in tqdm(jobs, desc="bench", disable=not progress):
        case = STUDY_CASES[case_name]
        if n_nodes is not None:
            case = dataclasses.replace(case, n_nodes=int(n_nodes))
        if model_name in runs:
            trained = load_trained(runs[model_name])
            model, params, stats, weights = trained.step, trained.params, trained.stats, "trained"
            config = run_config_label(runs[model_name], trained.config)
        else:
            model = make_step(create_model(model_name, get_config(model_name, tiny=tiny)))
            stats, weights = identity_stats(), "random init"
            config = "tiny config" if tiny else "study config"
        (x_prev, x_cur, node_type), source = _inputs(case, ds, seed, model)
        if model_name not in runs:
            if model_name not in inits:  # parameters do not depend on the node count
                inits[model_name] = model.init(
                    jax.random.key(seed), x_prev, x_cur, node_type, np.ones(len(node_type), bool))
            params = inits[model_name]
        steps = case.n_steps if max_steps is None else min(case.n_steps, int(max_steps))
        t = time_rollout(model, params, stats, x_prev, x_cur, node_type, steps, repeats=repeats)
        per_step = t["per_step_s"]
        case_s = per_step * case.n_steps
        full_s = per_step * case.full_frames
        row = {"model": model.name, "config": config, "case": case.name,
               "n_nodes": int(len(node_type)),
               "n_steps": case.n_steps, "timed_steps": steps, "extrapolated": steps < case.n_steps,
               "weights": weights, "positions": source, **t, "case_rollout_s": case_s,
               "full_length_s": full_s, "abaqus_s": case.abaqus_s,
               "speedup_vs_abaqus": case.abaqus_s / full_s}
        if case.kind in solver:
            row["solver_s"] = solver[case.kind]
            row["speedup_vs_solver"] = solver[case.kind] / full_s
        results.append(row)
    out = {"environment": environment(), "results": results, "note": (
        "Timing needs no trained weights: cost depends on architecture and shapes only. "
        "full_length_s = per-step time x all frames of the simulation (the study's x40/35, "
        "x200/160 scaling); speed-ups compare it with the solver's time per simulation. "
        "Radius graphs use the cell grid where it pays (full resolution; 'graph' and 'grid' "
        "in bench.json), else the dense search.")}
    if out_dir is not None:
        out_dir = pathlib.Path(out_dir)
        atomic_write_text(out_dir / "bench.json", json.dumps(out, indent=2))
        atomic_write_text(out_dir / "bench.md", bench_markdown(out))
        out["files"] = [str(out_dir / "bench.json"), str(out_dir / "bench.md")]
    out["table"] = bench_markdown(out)
    return out


def run_config_label(run_dir: str | pathlib.Path, config: dict) -> str:
    """``"run <folder> (hidden=32, processor_size=5)"``: a trained run and how its model config
    differs from the study's (or the tiny) config of its model."""
    train = config.get("train") or {}
    tiny = bool(train.get("tiny", False))
    used = dict(train.get("model_config") or {})
    try:
        base = config_to_dict(get_config(config["model"], tiny=tiny))
    except (KeyError, ConfigError):
        base = {}
    changed = {k: v for k, v in used.items() if base.get(k, object()) != v}
    detail = ", ".join(f"{k}={v}" for k, v in sorted(changed.items()))
    kind = "tiny" if tiny else "study"
    name = pathlib.Path(run_dir).name
    return f"run {name} ({kind} config" + (f" with {detail})" if detail else ")")


def _speedup(x: float) -> str:
    return f"x{x:.0f}" if x >= 10 else f"x{x:.2g}"


def bench_markdown(result: dict) -> str:
    """The benchmark as a markdown table with the environment beneath."""
    rows = [[r["model"], r.get("config", r["weights"]), r["case"], r["n_nodes"], f"{r['n_steps']}"
             + (f" (timed {r['timed_steps']})" if r["extrapolated"] else ""),
             r["compile_s"], r["rollout_s"], 1e3 * r["per_step_s"], r["full_length_s"],
             _speedup(r["speedup_vs_abaqus"]),
             _speedup(r["speedup_vs_solver"]) if "speedup_vs_solver" in r else "n/a",
             r["weights"]] for r in result["results"]]
    env = result["environment"]
    table = markdown_table(["model", "config", "case", "nodes", "steps", "compile s", "rollout s",
                            "ms/step", "full-length s", "vs Abaqus", "vs our solver",
                            "weights"], rows)
    return (f"# Rollout benchmark\n\n{table}\n{result['note']}\n\n"
            + "".join(f"- {k}: {v}\n" for k, v in env.items()))
