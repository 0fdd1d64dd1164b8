"""Benchmark the surrogates: parameter count, compile time and forward time per study config.

For every registered model (study hyper-parameters; ``--tiny`` for a smoke run) and every node
count (default 977 = BendVessel, 2,048 = the study's ClotEntry subsample), one jitted function
builds the graph from the positions and runs the model, as one rollout step does. Reported:

* ``params``: number of scalar parameters;
* ``compile_s``: time to lower and compile graph + model (``jax.jit(...).lower().compile()``);
* ``forward_ms``: median steady-state time of graph + model (``block_until_ready``);
* ``model_ms``: median time of the model alone on a precomputed graph;
* ``max_degree``: the largest real neighbour count before the cap (graph density check).

With ``--step`` the learned step of a rollout (:func:`thrombojax.simulator.step.make_step`:
graph + model + integration, one jitted call) is timed twice per node count: on the dense
radius search and on the cell grid sized from the two input frames
(:func:`thrombojax.simulator.grid_step.allocate_grid`; ``grid: none`` where it does not pay).
Reported per search: ``compile_s``, ``graph_ms`` (the graph alone), ``step_ms`` (median
of ``--repeats`` calls after compilation), ``overflow``, the largest output difference from the
dense step and ``ratio`` = grid ``step_ms`` / dense ``step_ms``.

Inputs are synthetic: a clot-like blob inside a tube of wall nodes in scaled [-1, 1]
coordinates, so radius graphs are about as dense as in the study (most nodes hit the cap of 32).
The header prints device, versions, date and the machine load (``os.getloadavg``), because
timings on a shared machine are only comparable at equal load.

Usage::

    python benchmarks/models.py [--models mgn transolver erwin] [--nodes 977 2048]
                                [--repeats 10] [--tiny] [--step] [--out results.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.eval.tables import environment
from thrombojax.models import MODEL_NAMES, count_params, create_model, get_config
from thrombojax.models.registry import identity_stats
from thrombojax.simulator.grid_step import allocate_grid
from thrombojax.simulator.step import make_step
from thrombojax.types import ModelInput, NodeType

__all__ = ["synthetic_inputs", "bench_model", "bench_step", "main"]


def synthetic_inputs(n_nodes: int, *, clot_fraction: float = 0.3, seed: int = 0) -> ModelInput:
    """A tube of wall nodes (radius 0.5, length 2 along x) with a clot blob inside, scaled coords.

    Args:
        n_nodes: number of nodes (all real).
        clot_fraction: fraction of clot nodes.
        seed: numpy seed.
    Returns:
        The :class:`ModelInput` with small random clot velocities and zero wall velocities.
    """
    rng = np.random.default_rng(seed)
    n_clot = int(round(clot_fraction * n_nodes))
    n_wall = n_nodes - n_clot
    theta = rng.uniform(0, 2 * np.pi, n_wall)
    wall = np.stack([rng.uniform(-1, 1, n_wall), 0.5 * np.cos(theta), 0.5 * np.sin(theta)], 1)
    u = rng.normal(size=(n_clot, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    clot = u * 0.4 * rng.uniform(0, 1, (n_clot, 1)) ** (1 / 3) * np.array([1.5, 1.0, 1.0])
    pos = np.concatenate([wall, clot]).astype(np.float32)
    vel = np.zeros_like(pos)
    vel[n_wall:] = 1e-3 * rng.normal(size=(n_clot, 3))
    node_type = np.full(n_nodes, NodeType.VESSEL, np.int32)
    node_type[n_wall:] = NodeType.CLOT
    return ModelInput(
        positions=jnp.asarray(pos),
        velocity=jnp.asarray(vel),
        node_type=jnp.asarray(node_type),
        mask=jnp.ones(n_nodes, bool),
    )


def _median_ms(fn, *args, repeats: int) -> float:
    jax.block_until_ready(fn(*args))  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def bench_model(name: str, n_nodes: int, *, tiny: bool = False, repeats: int = 10) -> dict:
    """Measure one model at one node count. Returns a dict of the figures (see module doc)."""
    model = create_model(name, get_config(name, tiny=tiny))
    inputs = synthetic_inputs(n_nodes)
    graph = jax.jit(model.build_graph)(inputs)
    params = model.init(jax.random.key(0), inputs, graph)

    def step(params, inputs):
        return model.apply(params, inputs, model.build_graph(inputs))

    t0 = time.perf_counter()
    compiled = jax.jit(step).lower(params, inputs).compile()
    compile_s = time.perf_counter() - t0
    model_only = jax.jit(lambda p, x, g: model.apply(p, x, g))
    nbrs = getattr(graph, "neighbors", graph)  # Erwin nests its radius graph
    counts = getattr(nbrs, "counts", None)
    return {
        "model": name,
        "nodes": n_nodes,
        "params": count_params(params),
        "compile_s": round(compile_s, 3),
        "forward_ms": round(_median_ms(compiled, params, inputs, repeats=repeats), 3),
        "model_ms": round(_median_ms(model_only, params, inputs, graph, repeats=repeats), 3),
        "max_degree": None if counts is None else int(jnp.max(counts)),
        "overflow": bool(graph.overflow),
    }


def bench_step(name: str, n_nodes: int, *, tiny: bool = False, repeats: int = 5) -> list[dict]:
    """Time the learned step (graph + forward) on the dense search and on the cell grid.

    Returns:
        One dict per search (``"dense"``, then ``"grid"``): see the module docstring.
    """
    model = create_model(name, get_config(name, tiny=tiny))
    inputs = synthetic_inputs(n_nodes)
    x_cur = np.asarray(inputs.positions)
    state = (x_cur - np.asarray(inputs.velocity), x_cur, np.asarray(inputs.node_type),
             np.ones(n_nodes, bool))
    dense = make_step(model)
    gridded = allocate_grid(dense, np.stack(state[:2]), state[2])
    stats = identity_stats()
    params = dense.init(jax.random.key(0), *state)
    rows, ref = [], None
    for label, step in (("dense", dense), ("grid", gridded)):
        t0 = time.perf_counter()
        compiled = jax.jit(step).lower(params, stats, *state).compile()
        compile_s = time.perf_counter() - t0
        out = compiled(params, stats, *state)
        ref = out.output if ref is None else ref
        graph_fn = jax.jit(step.build_graph)
        step_in = step.inputs(stats, *state)
        rows.append({
            "model": name, "nodes": n_nodes, "search": label,
            "grid": None if step.grid is None else str(step.grid),
            "compile_s": round(compile_s, 3),
            "graph_ms": round(_median_ms(graph_fn, step_in, repeats=repeats), 1),
            "step_ms": round(_median_ms(compiled, params, stats, *state, repeats=repeats), 1),
            "overflow": bool(out.overflow),
            "max_abs_diff": float(jnp.max(jnp.abs(out.output - ref))),
            "load_avg_1": round(os.getloadavg()[0], 2),
        })
    rows[1]["ratio"] = round(rows[1]["step_ms"] / rows[0]["step_ms"], 3)
    return rows


def _main_forward(args) -> list[dict]:
    cols = ["model", "nodes", "params", "compile_s", "forward_ms", "model_ms", "max_degree"]
    print(" | ".join(cols))
    rows = []
    for name in args.models:
        for n in args.nodes:
            row = bench_model(name, n, tiny=args.tiny, repeats=args.repeats)
            rows.append(row)
            print(" | ".join(str(row[c]) for c in cols), flush=True)
    return rows


def _main_step(args) -> list[dict]:
    cols = ["model", "nodes", "search", "compile_s", "graph_ms", "step_ms", "overflow",
            "max_abs_diff", "load_avg_1", "ratio", "grid"]
    print(" | ".join(cols))
    rows = []
    for name in args.models:
        for n in args.nodes:
            for row in bench_step(name, n, tiny=args.tiny, repeats=args.repeats):
                rows.append(row)
                print(" | ".join(str(row.get(c, "")) for c in cols), flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print a table (and write JSON with ``--out``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    default_models = [m for m in MODEL_NAMES if m != "constant_velocity"]
    parser.add_argument("--models", nargs="+", default=default_models, choices=MODEL_NAMES)
    parser.add_argument("--nodes", nargs="+", type=int, default=[977, 2048])
    parser.add_argument("--repeats", type=int, default=10, help="timed runs (median reported)")
    parser.add_argument("--tiny", action="store_true", help="tiny configs (smoke test)")
    parser.add_argument("--step", action="store_true",
                        help="time the learned step (graph + forward), dense vs cell grid")
    parser.add_argument("--out", help="write the results as JSON to this file")
    args = parser.parse_args(argv)

    env = environment()
    for key, value in env.items():
        print(f"# {key}: {value}")
    rows = _main_step(args) if args.step else _main_forward(args)
    env["load_avg_after"] = [round(x, 2) for x in os.getloadavg()]
    print(f"# load_avg_after: {env['load_avg_after']}")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"environment": env, "tiny": args.tiny, "results": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
