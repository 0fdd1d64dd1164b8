"""A human summary of a dataset file (``thrombojax info``)."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from tqdm import tqdm

from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.schema import bounding_box
from thrombojax.types import NodeType

__all__ = ["describe_dataset"]


def _num(value: Any, fmt: str = "{:.4g}") -> str:
    if isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool):
        return fmt.format(value)
    return "n/a"


def _span(values: list[int]) -> str:
    return str(values[0]) if min(values) == max(values) else f"{min(values)}..{max(values)}"


def _times(label: str, known: list) -> str:
    if not known:
        return f"{label}: n/a (not recorded)"
    return (f"{label}: {float(sum(known)):.1f} s total over {len(known)} simulations, "
            f"mean {float(np.mean(known)):.1f} s")


def _box(lo: np.ndarray, hi: np.ndarray) -> str:
    return " x ".join(f"[{a:.4g}, {b:.4g}]" for a, b in zip(lo, hi, strict=True))


def describe_dataset(path: str | os.PathLike, *, progress: bool = False) -> str:
    """Read and validate every simulation of a dataset and summarise it.

    Reads one simulation at a time (memory stays at one simulation).

    Args:
        path: dataset file.
        progress: show a progress bar over simulations.
    Returns:
        A multi-line summary: file attributes, then one row per simulation (frames, nodes,
        clot nodes and fraction, dt, solver and reference wall times, bounding box), then totals.
    Raises:
        DatasetError / FileNotFoundError: the file or one simulation is invalid.
    """
    ds = open_dataset(path)
    a = ds.attrs
    lines = [
        f"dataset  {ds.path}",
        f"name     {a.get('name', 'n/a')}   source: {a.get('source', 'n/a')}   "
        f"units: {a.get('units', 'n/a')}",
        f"kind     {a.get('kind', 'unknown')}   rollouts skip the first "
        f"{a.get('skip_frames', 0)} frames",
        f"created  {a.get('created', 'n/a')}   format: {a.get('format')} v{a.get('version')}",
        f"simulations: {len(ds)}",
        "",
        f"{'simulation':<20} {'frames':>6} {'nodes':>7} {'clot':>7} {'clot%':>6} {'dt':>9} "
        f"{'solver_s':>9} {'ref_s':>9}  bounding box",
    ]
    lo_all = np.full(3, np.inf)
    hi_all = np.full(3, -np.inf)
    frames, nodes, clot_total, solver, reference = [], [], 0, [], []
    for name in tqdm(ds.names, desc="reading", unit="sim", disable=not progress):
        sim = ds[name]
        n_clot = int((sim.node_type == NodeType.CLOT).sum())
        lo, hi = bounding_box(sim.positions)
        lo_all, hi_all = np.minimum(lo_all, lo), np.maximum(hi_all, hi)
        frames.append(sim.n_frames)
        nodes.append(sim.n_nodes)
        clot_total += n_clot
        s_time = sim.attrs.get("solver_wall_time_s")
        r_time = sim.attrs.get("reference_wall_time_s")
        solver.append(s_time)
        reference.append(r_time)
        lines.append(
            f"{name:<20} {sim.n_frames:>6} {sim.n_nodes:>7} {n_clot:>7} "
            f"{100.0 * n_clot / sim.n_nodes:>6.1f} {_num(sim.attrs.get('dt')):>9} "
            f"{_num(s_time, '{:.1f}'):>9} {_num(r_time, '{:.1f}'):>9}  {_box(lo, hi)}"
        )
    solver_known = [s for s in solver if _num(s) != "n/a"]
    ref_known = [r for r in reference if _num(r) != "n/a"]
    lines += [
        "",
        f"frames   {_span(frames)} per simulation, {sum(frames)} in total",
        f"nodes    {_span(nodes)} per simulation; clot fraction "
        f"{clot_total / sum(nodes):.3f} over all simulations",
        f"bounding box (all simulations, all frames): {_box(lo_all, hi_all)}",
        _times("solver wall time (measured)", solver_known),
        _times("reference wall time (recorded)", ref_known),
    ]
    return "\n".join(lines)
