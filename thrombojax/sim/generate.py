"""Run a preset and write its dataset (the ``thrombojax generate`` command).

Each case runs until the clot has left the vessel (:func:`thrombojax.sim.solver.run`); its
densely stored frames are linearly interpolated in time to exactly ``n_frames + 1`` frames
from the start to the exit. Wall nodes (rings of points) are appended after the clot nodes,
and every position is rotated by the case's rotation (BendVessel: ``index * 10`` degrees about
x; the physics is rotation invariant, so all cases share one unrotated mesh and one compile;
a preset that draws a bend's shape per simulation compiles once per centreline length).
Cases of a preset with ``batch_size > 1`` run together under ``jax.vmap``.
"""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from tqdm import tqdm

from thrombojax.errors import ConfigError, ThrombojaxError
from thrombojax.io.hdf5 import DatasetWriter, Simulation
from thrombojax.io.outputs import atomic_path, check_targets
from thrombojax.sim.cases import Case, build_case, stack_cases
from thrombojax.sim.material import element_J
from thrombojax.sim.presets import Preset, get_preset
from thrombojax.sim.solver import RunResult, run, run_batch
from thrombojax.types import NodeType

__all__ = ["simulate", "simulate_cases", "compile_cases", "generate_dataset", "resample", "SOURCE"]

SOURCE = "thrombojax.sim (explicit FEM, JAX)"


def resample(frames: np.ndarray, count: int, n_out: int) -> np.ndarray:
    """Linearly interpolate ``count`` equally spaced frames ``[>=count, N, 3]`` to ``n_out``."""
    u = np.linspace(0.0, count - 1, n_out)
    lo = np.minimum(np.floor(u).astype(int), count - 2)
    w = (u - lo)[:, None, None]
    return ((1.0 - w) * frames[lo] + w * frames[lo + 1]).astype(np.float32)


def _to_simulation(preset: Preset, case: Case, res: RunResult, wall_time: float) -> Simulation:
    count, stride = int(res.count), int(res.stride)
    if not bool(res.exited):
        raise ThrombojaxError(
            f"preset {preset.name!r}: simulation {case.index}: the clot did not leave the vessel "
            f"within {preset.max_substeps} substeps; raise max_substeps or the drive"
        )
    frames = np.asarray(res.frames[:count], np.float64)
    if not np.all(np.isfinite(frames)):
        raise ThrombojaxError(
            f"preset {preset.name!r}: simulation {case.index}: non-finite "
            "positions (unstable substep)"
        )
    clot = resample(frames, count, preset.n_frames + 1).astype(np.float64)
    j = np.asarray(jax.vmap(lambda x: element_J(x, case.tets, case.params.dm_inv))(clot))
    dt_sub = float(case.params.dt)
    t_end = (count - 1) * stride * dt_sub
    ke, ee = np.asarray(res.kinetic[:count]), np.asarray(res.elastic[:count])
    t_dense = np.arange(count) * stride * dt_sub
    before_exit = np.asarray(res.inside[:count]) >= 1.0
    moving = (t_dense > preset.ramp_time) & before_exit
    centroid = clot.mean(axis=1)
    travel = float(np.linalg.norm(np.diff(centroid, axis=0), axis=1).sum())
    positions = np.concatenate(
        [clot, np.broadcast_to(case.wall_points, (len(clot),) + case.wall_points.shape)], axis=1
    )
    positions = (positions @ case.rotation.T).astype(np.float32)
    n_clot = clot.shape[1]
    node_type = np.concatenate(
        [np.full(n_clot, NodeType.CLOT), np.full(len(case.wall_points), NodeType.VESSEL)]
    )
    attrs = {
        **case.attrs,
        "dt": t_end / preset.n_frames,
        "end_time": t_end,
        "substeps": int(res.steps),
        "solver_wall_time_s": float(wall_time),
        "reference_wall_time_s": float(preset.reference_wall_time_s),
        "preset": preset.name,
        "min_J": float(j.min()),
        "max_penetration_rel": float(res.max_penetration),
        "travel_clot_lengths": travel / preset.clot_length,
        "kinetic_to_elastic": float(ke[moving].sum() / max(ee[moving].sum(), 1e-30)),
        "max_kinetic_to_elastic": float(np.max(ke[moving] / np.maximum(ee[moving], 1e-30)))
        if moving.any()
        else 0.0,
    }
    return Simulation(
        name=f"{preset.name}_{case.index:03d}", positions=positions,
        node_type=node_type.astype(np.int8), clot_cells=case.tets.astype(np.int32),
        wall_cells=(case.wall_cells + n_clot).astype(np.int32), attrs=attrs,
    )  # fmt: skip


def _run_kwargs(preset: Preset) -> dict:
    return {
        "n_buffer": preset.n_buffer,
        "max_substeps": preset.max_substeps,
        "elem_bulk": preset.elem_bulk,
    }


def _one_vessel(preset: Preset, cases: list[Case]) -> None:
    """Refuse a batch whose cases do not share one vessel (the run takes one centreline)."""
    first = np.asarray(cases[0].centreline.points)
    for case in cases[1:]:
        other = np.asarray(case.centreline.points)
        if other.shape != first.shape or not np.array_equal(other, first):
            raise ConfigError(
                f"preset {preset.name!r}: simulations {cases[0].index} and {case.index} have "
                "different vessels and cannot run in one batch; use batch_size 1")


def compile_cases(preset: Preset, cases: list[Case]):
    """Compile the run for these cases' shapes; returns ``(compiled, args, seconds)``."""
    _one_vessel(preset, cases)
    cl = jax.tree.map(jnp.asarray, cases[0].centreline)
    tets = jnp.asarray(cases[0].tets)
    fn, params = (run, cases[0].params) if len(cases) == 1 else (run_batch, stack_cases(cases))
    t0 = time.perf_counter()
    compiled = fn.lower(params, cl, tets, **_run_kwargs(preset)).compile()
    return compiled, (params, cl, tets), time.perf_counter() - t0


def simulate_cases(preset: Preset, cases: list[Case], compiled=None) -> list[Simulation]:
    """Run cases that share one mesh together (``vmap``) and convert them to simulations.

    Args:
        preset: the preset.
        cases: cases with identical mesh shapes.
        compiled: a run compiled by a previous call for the same shapes (else compiled here).

    The measured ``solver_wall_time_s`` excludes compilation and is the batch time divided by
    the number of cases; the compile time is stored as ``solver_compile_time_s`` (0 when
    ``compiled`` was given).
    """
    fresh, args, t_compile = compile_cases(preset, cases) if compiled is None else (None, None, 0.0)
    if compiled is None:
        compiled = fresh
    else:
        _one_vessel(preset, cases)
        cl = jax.tree.map(jnp.asarray, cases[0].centreline)
        params = cases[0].params if len(cases) == 1 else stack_cases(cases)
        args = (params, cl, jnp.asarray(cases[0].tets))
    t1 = time.perf_counter()
    res = jax.block_until_ready(compiled(*args, max_substeps=preset.max_substeps))
    wall = (time.perf_counter() - t1) / len(cases)
    out = []
    for i, case in enumerate(cases):
        one = res if len(cases) == 1 else jax.tree.map(lambda a, i=i: a[i], res)
        sim = _to_simulation(preset, case, one, wall)
        sim.attrs["solver_compile_time_s"] = t_compile
        out.append(sim)
    return out


def simulate(preset: Preset | str, index: int, *, seed: int = 0) -> Simulation:
    """Simulate case ``index`` of a preset (one simulation; wall time measured in attrs).

    Args:
        preset: a :class:`Preset` or its name.
        index: simulation index (BendVessel: rotation ``index * 10`` degrees).
        seed: dataset seed.

    Returns:
        The :class:`~thrombojax.io.hdf5.Simulation`.
    """
    preset = get_preset(preset) if isinstance(preset, str) else preset
    return simulate_cases(preset, [build_case(preset, index, seed)])[0]


def generate_dataset(
    preset: Preset | str,
    out: str | Path,
    *,
    n_sims: int | None = None,
    seed: int = 0,
    plot: bool = False,
    progress: bool = True,
    force: bool = False,
) -> Path:
    """Generate a preset's dataset into ``out`` (HDF5, written atomically, streamed).

    Args:
        preset: a :class:`Preset` or its name.
        out: target file.
        n_sims: number of simulations (default: the preset's).
        seed: dataset seed (the same seed gives the same arrays).
        plot: also write ``<out>.png`` with a few frames of the first simulation (the path
            ``out.with_suffix(".png")``).
        progress: show a progress bar.
        force: replace an existing ``out`` (and plot); without it an existing file is refused
            (:class:`~thrombojax.errors.OutputError`) before anything runs.

    Returns:
        The path written.
    """
    preset = get_preset(preset) if isinstance(preset, str) else preset
    n = preset.n_sims if n_sims is None else int(n_sims)
    if n < 1:
        raise ConfigError(f"generate: --sims must be >= 1, got {n}")
    if seed < 0:
        raise ConfigError(f"generate: --seed must be >= 0, got {seed}")
    out = Path(out)
    if out.suffix.lower() not in (".h5", ".hdf5"):
        raise ConfigError(f"generate: --out {out}: a dataset file must end in .h5 or .hdf5")
    png = out.with_suffix(".png")
    check_targets([out, png] if plot else [out], force=force)
    first = None
    compiled = {}  # one compiled run per centreline length (a bend drawn per case varies it)
    bar = tqdm(total=n, desc=f"generate {preset.name}", unit="sim", disable=not progress)
    with DatasetWriter(
        out,
        name=preset.name,
        source=SOURCE,
        overwrite=force,
        generator_config={**preset.to_dict(), "seed": seed, "n_sims": n},
        kind=preset.study,
        skip_frames=preset.skip_frames,
    ) as w:
        for start in range(0, n, preset.batch_size):
            idx = list(range(start, min(start + preset.batch_size, n)))
            # pad a short last batch with repeats so every batch has one compiled shape
            padded = idx + [idx[-1]] * (min(preset.batch_size, n) - len(idx))
            cases = [build_case(preset, i, seed) for i in padded]
            key = np.shape(cases[0].centreline.points)
            if key not in compiled:
                compiled[key] = compile_cases(preset, cases)[0]
            for sim in simulate_cases(preset, cases, compiled[key])[: len(idx)]:
                w.add(sim)
                first = first or sim
                bar.update(1)
    bar.close()
    if plot:
        from thrombojax.sim.plot import plot_simulation

        with atomic_path(png) as tmp:
            plot_simulation(first, tmp, units="vessel radius")  # the file's unit
    return out
