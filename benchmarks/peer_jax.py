"""The thrombojax side of ``benchmarks/peer.py``: one worker process, the study configs.

Cases, as a user runs them (study configs, :func:`thrombojax.models.registry.get_config`):

* ``step``: the learned step of a rollout, :func:`thrombojax.simulator.step.make_step` jitted
  (graph from the positions + model + integration in one compiled call, as
  ``benchmarks/models.py --step``) with :func:`thrombojax.xla_options.jit`, the compiler
  options thrombojax's rollouts use (as ``forward``; ``rollout`` and ``train`` get them from
  :data:`~thrombojax.simulator.rollout.rollout_jit` and
  :func:`~thrombojax.train.step.make_train_step`);
* ``rollout``: :data:`thrombojax.simulator.rollout.rollout_jit`, the ``lax.scan`` rollout of
  ``--rollout-steps`` steps compiled once;
* ``forward``: graph + model in one jitted call at full resolution, the graph on the cell grid
  sized by :func:`thrombojax.simulator.grid_step.allocate_grid` where it pays (as
  ``thrombojax.eval.rollouts.rollout_simulation`` does), grown by
  :func:`~thrombojax.simulator.grid_step.run_checked` if it overflowed;
* ``train``: :func:`thrombojax.train.step.make_train_step` (graph, forward, backward, AdamW with
  the study's learning rate and weight decay 0.01) on one sample, the buffers donated, as
  ``benchmarks/train_step.py``.

Run by the parent as ``python benchmarks/peer_jax.py SPEC_JSON`` (``benchmarks/peer_common.py``
describes the protocol).
"""

from __future__ import annotations

import json
import os
import sys

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.data.batching import Batch
from thrombojax.graph.neighbors import graph_overflow
from thrombojax.models import count_params, create_model, get_config
from thrombojax.simulator.grid_step import allocate_grid, run_checked
from thrombojax.simulator.rollout import rollout_jit
from thrombojax.simulator.step import make_step
from thrombojax.study import training_defaults
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import init_state, make_train_step
from thrombojax.types import TargetStats
from thrombojax.xla_options import jit as xla_jit

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peer_common import STATS, Case, Inputs, read_inputs, serve  # noqa: E402

__all__ = ["target_stats", "edges_per_node", "prepare", "versions"]


def target_stats() -> TargetStats:
    """:data:`peer_common.STATS` as a :class:`TargetStats`."""
    return TargetStats(mean=jnp.full(3, STATS["mean"], jnp.float32),
                       std=jnp.full(3, STATS["std"], jnp.float32),
                       velocity_std=jnp.float32(STATS["velocity_std"]))


def edges_per_node(step, stats, state) -> float:
    """Mean number of graph edges per node (after the cap) of the step's graph of ``state``."""
    graph = jax.jit(step.build_graph)(step.inputs(stats, *state))
    nbrs = getattr(graph, "neighbors", graph)  # Erwin nests its radius graph
    k = nbrs.indices.shape[-1]
    return float(jnp.mean(jnp.minimum(nbrs.counts, k)))


def _state(inp: Inputs) -> tuple:
    n = inp.n_nodes
    return (jnp.asarray(inp.x_prev), jnp.asarray(inp.x_cur), jnp.asarray(inp.node_type),
            jnp.ones(n, bool))


def _step_case(name, model, params, stats, inp, spec) -> Case:
    step = make_step(model)
    state = _state(inp)
    compiled = xla_jit(step, model=name).lower(params, stats, *state).compile()
    jax.block_until_ready(compiled(params, stats, *state))
    return Case(f"{name}|step|{inp.n_nodes}", lambda: jax.block_until_ready(
        compiled(params, stats, *state).positions), repeats=spec["repeats"])


def _rollout_case(name, model, params, stats, inp, spec) -> Case:
    step, n_steps = make_step(model), int(spec["rollout_steps"])
    state = _state(inp)

    def run():
        return jax.block_until_ready(rollout_jit(step, params, stats, *state, n_steps, None)[0])

    run()  # compile + one warm rollout
    return Case(f"{name}|rollout|{inp.n_nodes}", run, model_steps=n_steps)


def _forward_case(name, model, params, stats, inp, spec) -> Case:
    state = _state(inp)
    frames = np.stack([inp.x_prev, inp.x_cur])
    step = allocate_grid(make_step(model), frames, inp.node_type)

    compiled = {}

    def run(s):  # graph + model, and the grid's overflow flag
        def fn(p, *st):
            inputs = s.inputs(stats, *st)
            graph = s.build_graph(inputs)
            return model.apply(p, inputs, graph), graph_overflow(graph)
        compiled[s] = xla_jit(fn, model=name)
        return compiled[s](params, *state)

    _, step = run_checked(run, step, what="forward")  # compiled, warm, grown if it overflowed
    fn = compiled[step]
    return Case(f"{name}|forward|{inp.n_nodes}",
                lambda: jax.block_until_ready(fn(params, *state)[0]),
                info={"grid": step.grid is not None,
                      "edges_per_node": round(edges_per_node(step, stats, state), 2)})


def _train_case(name, model, params, stats, inp, spec) -> Case:
    n = inp.n_nodes
    host = Batch(frames=np.stack([inp.x_prev, inp.x_cur, inp.x_next])[None],
                 node_type=inp.node_type[None], mask=np.ones((1, n), bool),
                 generated=np.zeros(1, bool))
    tx = make_optimizer(make_schedule(training_defaults(name)["lr"], 1000, 10))
    box = [init_state(model, tx, jax.random.PRNGKey(0), host)]
    step = make_train_step(model, tx, stats, donate=True)
    data, key = jax.tree.map(jnp.asarray, host), jax.random.PRNGKey(1)

    def run():
        box[0], metrics = step(box[0], data, key)
        return jax.block_until_ready((box[0], metrics))

    for _ in range(2):  # compile + one warm step
        run()
    return Case(f"{name}|train|{n}", run, repeats=spec["repeats"])


_BUILDERS = {"step": _step_case, "rollout": _rollout_case, "forward": _forward_case,
             "train": _train_case}


def prepare(spec: dict) -> list[Case]:
    """Build, compile and warm up every case of ``spec`` (``cases``: ``[model, kind, nodes]``)."""
    stats, cases = target_stats(), []
    for name, kind, n in spec["cases"]:
        model = create_model(name, get_config(name, tiny=spec["tiny"]))
        inp = read_inputs(spec["inputs"][str(n)])
        params = make_step(model).init(jax.random.key(0), *_state(inp))
        case = _BUILDERS[kind](name, model, params, stats, inp, spec)
        case.info["params"] = count_params(params)
        if "edges_per_node" not in case.info:  # the dense graph every other case builds
            case.info["edges_per_node"] = round(
                edges_per_node(make_step(model), stats, _state(inp)), 2)
        cases.append(case)
    return cases


def versions() -> dict:
    """Versions of the JAX stack (``jax``, ``jaxlib``, ``flax``)."""
    import flax
    return {"jax": jax.__version__, "jaxlib": getattr(jax.lib, "__version__", None),
            "flax": flax.__version__, "device": str(jax.devices()[0].device_kind)}


if __name__ == "__main__":
    _x, _gelu = jnp.ones(1 << 17), jax.jit(jax.nn.gelu)
    serve(prepare, json.loads(sys.argv[1]), versions(),
          probe=lambda: jax.block_until_ready(_gelu(_x)))
