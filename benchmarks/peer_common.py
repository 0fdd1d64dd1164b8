"""What both sides of ``benchmarks/peer.py`` share: the inputs, the statistics and the worker loop.

The parent (``benchmarks/peer.py``) writes the inputs of every node count once, with numpy, to
an ``.npz`` file (:func:`write_inputs`); the JAX worker (``benchmarks/peer_jax.py``) and the
PyTorch workers (``benchmarks/peer_torch.py``) read the same file (:func:`read_inputs`), so both
sides build their radius graphs from the same positions.

A worker is a long-lived process: it prepares every case it was given (builds the model,
compiles or warms it up, one warm call), prints ``{"ready": ...}`` as one JSON line, then for
every line read from stdin times each case ``repeats`` times and prints ``{"round": [...]}``
(:func:`serve`). Each timing records the minor page faults of the call
(``resource.getrusage().ru_minflt`` deltas), as ``benchmarks/train_step.py`` does.
"""

from __future__ import annotations

import dataclasses
import json
import os
import resource
import sys
import time
from collections.abc import Callable

import numpy as np

__all__ = ["STATS", "Inputs", "write_inputs", "read_inputs", "Case", "serve", "CASE_LABELS"]

STATS: dict[str, float] = {"mean": 0.0, "std": 1e-5, "velocity_std": 1e-3}
"""Target statistics of both sides: the velocity feature is ``v / 1e-3`` (order one for the
synthetic clot velocities) and the output is scaled by ``1e-5``, so an untrained model moves the
clot by well under the graph radius over a 40-step rollout (the graphs stay as dense)."""

CASE_LABELS: dict[str, str] = {
    "step": "rollout step",
    "rollout": "rollout",
    "forward": "forward",
    "train": "train step",
}
"""Printed name of every case kind."""


@dataclasses.dataclass(frozen=True)
class Inputs:
    """One synthetic sample: three frames and the node types (numpy, float32 / int32).

    Attributes:
        x_prev, x_cur, x_next: ``[N, 3]`` positions s_{t-1}, s_t, s_{t+1} (scaled coordinates).
        node_type: ``[N]`` NodeType values (0 vessel, 1 clot).
    """

    x_prev: np.ndarray
    x_cur: np.ndarray
    x_next: np.ndarray
    node_type: np.ndarray

    @property
    def n_nodes(self) -> int:
        return int(self.x_cur.shape[0])


def write_inputs(path: str, n_nodes: int, seed: int = 0) -> None:
    """Write the sample of ``n_nodes`` nodes to ``path`` (``.npz``).

    Positions and velocities are ``synthetic_inputs`` of ``benchmarks/models.py`` (a tube of
    vessel nodes with a clot blob, most nodes at the neighbour cap of 32); the next frame adds
    a small random acceleration to the clot nodes (the training target).
    """
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from models import synthetic_inputs  # benchmarks/ is not a package

    sample = synthetic_inputs(n_nodes, seed=seed)
    x_cur = np.asarray(sample.positions, np.float32)
    vel = np.asarray(sample.velocity, np.float32)
    node_type = np.asarray(sample.node_type, np.int32)
    rng = np.random.default_rng(seed + 1)
    accel = 1e-5 * rng.normal(size=x_cur.shape).astype(np.float32) * (node_type == 1)[:, None]
    np.savez(path, x_prev=x_cur - vel, x_cur=x_cur, x_next=x_cur + vel + accel,
             node_type=node_type)


def read_inputs(path: str) -> Inputs:
    """Read a sample written by :func:`write_inputs`."""
    with np.load(path) as f:
        return Inputs(**{k: np.array(f[k]) for k in ("x_prev", "x_cur", "x_next", "node_type")})


@dataclasses.dataclass
class Case:
    """One prepared case of a worker.

    Attributes:
        key: ``"model|kind|nodes"``.
        run: one timed call; it blocks until its result is computed.
        model_steps: learned steps in one call (40 for the 40-step rollout), to report faults
            per step.
        repeats: timed calls per round.
        info: what the worker reports about the case (parameters, edges per node, ...).
    """

    key: str
    run: Callable[[], object]
    model_steps: int = 1
    repeats: int = 1
    info: dict = dataclasses.field(default_factory=dict)


def _emit(msg: dict) -> None:
    print(json.dumps(msg), flush=True)


def _probe_us(probe: Callable[[], object], calls: int = 21) -> float:
    """Median microseconds of ``probe()`` (a small parallel op: its time is mostly the cost of
    waking the worker threads, which grows when they wait for a busy core)."""
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        probe()
        times.append(1e6 * (time.perf_counter() - t0))
    return sorted(times)[calls // 2]


def serve(prepare: Callable[[dict], list[Case]], spec: dict, versions: dict,
          probe: Callable[[], object] | None = None) -> None:
    """Run a worker: prepare the cases of ``spec``, then time them once per stdin line.

    Args:
        prepare: builds the :class:`Case` list of a spec (compilation and warm-up included).
        spec: the worker's spec from the parent (cases, repeats, paths).
        versions: library versions to report with ``ready``.
        probe: a small multi-threaded op timed after every round (``probe_us``: a contention
            check; see :func:`_probe_us`).
    """
    t0 = time.perf_counter()
    cases = prepare(spec)
    _emit({"ready": True, "prepare_s": round(time.perf_counter() - t0, 1), "versions": versions,
           "info": {c.key: c.info for c in cases},
           "allocator": os.environ.get("LD_PRELOAD", "") or "default"})
    for _ in sys.stdin:
        out = []
        for case in cases:
            for _ in range(case.repeats):
                faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
                t1 = time.perf_counter()
                case.run()
                ms = 1e3 * (time.perf_counter() - t1)
                faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
                out.append({"key": case.key, "ms": ms,
                            "faults_per_step": faults / case.model_steps})
        _emit({"round": out, "load": [round(x, 2) for x in os.getloadavg()],
               "probe_us": None if probe is None else round(_probe_us(probe), 1)})
