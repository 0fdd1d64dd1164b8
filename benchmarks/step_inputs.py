"""What a learned step's geometric inputs cost: the step of each recipe, and its parts alone.

The rollout recipes that follow the vessel add inputs that are computed from the frame at every
step, inside the compiled rollout: the wall features (distance and direction to the nearest
vessel node, ``--wall-features``), the vessel-axis velocity split (``--axis-features``) and the
vessel-following prior (``--follow-axis``). Their searches are dense (``N x N``), so at a few
thousand nodes they can cost more than the model. This script times, per node count:

* the learned step (:func:`thrombojax.simulator.step.make_step`: inputs, graph, model,
  integration; one jitted call) with the inputs added one at a time: ``plain``, ``+ wall``,
  ``+ axis``, ``+ prior`` (the last is the input set of the ClotEntry recipes
  ``follow_*`` of ``experiments/ladder_rungs.py``), and its ratio to ``plain``; and the last
  as a rollout runs it, given the :class:`~thrombojax.simulator.step.StepContext` made once
  (``, rollout context``: the rigid vessel's wall search not repeated); and that step in a
  compiled rollout of :data:`ROLLOUT_STEPS` steps, per step, with the context (as
  :func:`thrombojax.simulator.rollout.rollout_jit` runs it) and with every step searching its
  own frame (how rollouts ran before the context);
* each input function alone (one jitted call): ``wall_node_features``, ``vessel_axis``, and
  ``local_wall_plane`` (the wall normals ``vessel_axis`` starts from; its ``N x N`` nearest-node
  search), ``vessel_axis`` given the context, and the model on a precomputed graph
  (``model``).

Times are medians of ``--repeats`` calls after compilation (``block_until_ready``). The model is
the stability ladder's small MeshGraphNet (hidden 32, 5 blocks, 12 neighbours; ``--size study``:
the study's; ``--size tiny``: the test suite's, a smoke run). Inputs are the synthetic tube of
``benchmarks/models.py`` (wall radius 0.5 in scaled coordinates, a clot blob inside); distances
follow the recipes in vessel radii: wall cutoff 0.5 r, axis and prior width 2 r. The header
prints device, versions, date and load.

Usage::

    python benchmarks/step_inputs.py [--nodes 977 2048] [--repeats 10] [--size small|study|tiny]
                                     [--out results.json] [--md results.md]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import jax
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from models import _median_ms, synthetic_inputs  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.graph.vessel_axis import vessel_axis  # noqa: E402
from thrombojax.graph.wall_nodes import local_wall_plane, wall_node_features  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, refuse_targets  # noqa: E402
from thrombojax.models import create_model, get_config  # noqa: E402
from thrombojax.models.registry import identity_stats  # noqa: E402
from thrombojax.simulator.rollout import rollout_jit  # noqa: E402
from thrombojax.simulator.step import make_step  # noqa: E402

__all__ = ["RADIUS", "STEPS", "ROLLOUT_STEPS", "bench_inputs", "main"]

RADIUS = 0.5
"""The synthetic tube's radius (scaled coordinates): one vessel radius, r."""

STEPS: tuple[tuple[str, dict], ...] = (
    ("plain", {}),
    ("+ wall", {"wall_cutoff": 0.5 * RADIUS}),
    ("+ axis", {"wall_cutoff": 0.5 * RADIUS, "axis_radius": 2 * RADIUS}),
    ("+ prior", {"wall_cutoff": 0.5 * RADIUS, "axis_radius": 2 * RADIUS,
                 "prior_radius": 2 * RADIUS}),
)
"""The steps timed: inputs added one at a time (``make_step`` keyword arguments)."""

SMALL = {"hidden": 32, "processor_size": 5, "mlp_layers": 2, "max_neighbors": 12}
"""The stability ladder's small MeshGraphNet (``experiments/ladder_rungs.py``)."""


ROLLOUT_STEPS = 20
"""Steps of the timed rollouts (their rows give milliseconds per step)."""


def _rollout_with_context(step, params, stats, x_prev, x_cur, node_type, mask):
    return rollout_jit(step, params, stats, x_prev, x_cur, node_type, mask, ROLLOUT_STEPS)[0]


def _rollout_without_context(step, params, stats, x_prev, x_cur, node_type, mask):
    def body(carry, _):
        prev, cur = carry
        nxt = step(params, stats, prev, cur, node_type, mask).positions
        return (cur, nxt), nxt

    return jax.lax.scan(body, (x_prev, x_cur), None, length=ROLLOUT_STEPS)[1]


def bench_inputs(n_nodes: int, *, size: str = "small", repeats: int = 10) -> list[dict]:
    """Time the steps of :data:`STEPS` and the input functions alone at ``n_nodes`` nodes.

    Returns:
        One dict per row: ``what``, ``nodes``, ``ms`` (median) and, for steps, ``ratio`` to
        the plain step.
    """
    config = {"small": SMALL, "study": {}, "tiny": {"tiny": True}}[size]
    model = create_model("mgn", get_config("mgn", **config))
    inputs = synthetic_inputs(n_nodes)
    x_cur = np.asarray(inputs.positions)
    node_type, mask = np.asarray(inputs.node_type), np.ones(n_nodes, bool)
    state = (x_cur - np.asarray(inputs.velocity), x_cur, node_type, mask)
    stats = identity_stats()
    rows: list[dict] = []
    for label, kwargs in STEPS:
        step = make_step(model, **kwargs)
        params = step.init(jax.random.key(0), *state)
        call = jax.jit(lambda p, a, b, s=step: s(p, stats, a, b, node_type, mask).positions)
        ms = round(_median_ms(call, params, *state[:2], repeats=repeats), 1)
        rows.append({"what": f"step {label}", "nodes": n_nodes, "ms": ms,
                     "ratio": round(ms / (rows[0]["ms"] if rows else ms), 2)})
    # the last step as a rollout runs it: the vessel's wall search made once (StepContext)
    context = jax.jit(step.context)(x_cur, node_type, mask)
    call = jax.jit(lambda p, a, b, c, s=step: s(p, stats, a, b, node_type, mask,
                                                  context=c).positions)
    ms = round(_median_ms(call, params, *state[:2], context, repeats=repeats), 1)
    rows.append({"what": f"step {STEPS[-1][0]}, rollout context", "nodes": n_nodes, "ms": ms,
                 "ratio": round(ms / rows[0]["ms"], 2)})
    # and in a rollout of ROLLOUT_STEPS steps, per step: the compiled rollout (context made
    # once) against the same scan with each step searching its own frame (before the context)
    plain_ms = rows[0]["ms"]
    for label, fn in (("search every step", _rollout_without_context),
                      ("rollout context", _rollout_with_context)):
        call = jax.jit(lambda p, a, b, s=step, f=fn: f(s, p, stats, a, b, node_type, mask))
        ms = round(_median_ms(call, params, *state[:2], repeats=max(1, repeats // 4))
                   / ROLLOUT_STEPS, 1)
        rows.append({"what": f"rollout {STEPS[-1][0]}, {label}", "nodes": n_nodes, "ms": ms,
                     "ratio": round(ms / plain_ms, 2)})
    plain = make_step(model)  # the model alone, on the plain step's input and graph
    model_in = plain.inputs(stats, *state)
    graph = jax.jit(plain.build_graph)(model_in)
    params = plain.init(jax.random.key(0), *state)
    model_ms = _median_ms(jax.jit(model.apply), params, model_in, graph, repeats=repeats)
    parts = (
        ("model", None),
        ("wall_node_features", lambda x: wall_node_features(x, node_type, mask,
                                                            cutoff=0.5 * RADIUS)),
        ("local_wall_plane", lambda x: local_wall_plane(x, node_type, mask)),
        ("vessel_axis", lambda x: vessel_axis(x, node_type, mask, radius=2 * RADIUS)),
        ("vessel_axis, rollout context", lambda x: vessel_axis(
            x, node_type, mask, radius=2 * RADIUS, patch=context.global_patch)),
    )
    for label, fn in parts:
        ms = model_ms if fn is None else _median_ms(jax.jit(fn), x_cur, repeats=repeats)
        rows.append({"what": label, "nodes": n_nodes, "ms": round(ms, 1)})
    return rows


def _markdown(rows: list[dict], env: dict, size: str) -> str:
    lines = [f"# A learned step's geometric inputs ({size} MeshGraphNet, synthetic tube)", "",
             "| what | nodes | median ms | ratio to the plain step |",
             "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['what']} | {r['nodes']} | {r['ms']} | {r.get('ratio', '-')} |")
    lines += ["", "Steps: inputs added one at a time (wall cutoff 0.5 r; axis features and prior "
              "width 2 r); 'rollout context': the last step given the vessel's wall search made "
              "once, as every rollout runs it; 'rollout' rows: ms per step of a "
              f"{ROLLOUT_STEPS}-step compiled rollout of that step. The other rows are each "
              "part alone, one jitted call. Medians after compilation.", ""]
    lines += [f"- {k}: {v}" for k, v in env.items()]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--nodes", type=int, nargs="+", default=[977, 2048])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--size", choices=("small", "study", "tiny"), default="small",
                        help="the ladder's small MeshGraphNet (default), the study's, or the "
                        "tiny test model (a smoke run)")
    parser.add_argument("--out", help="JSON file to write (refused if it exists, unless --force)")
    parser.add_argument("--md",
                        help="markdown table to write (refused if it exists, unless --force)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out/--md")
    args = parser.parse_args(argv)
    refuse_targets(parser, (args.out, args.md), force=args.force, what="report")
    env = environment()
    print(" ".join(f"{k}={v}" for k, v in env.items()), flush=True)
    rows = []
    for n in args.nodes:
        for row in bench_inputs(n, size=args.size, repeats=args.repeats):
            rows.append(row)
            print(" | ".join(f"{k}={v}" for k, v in row.items()), flush=True)
    if args.out:
        atomic_write_text(args.out, json.dumps({"environment": env, "rows": rows}, indent=1))
    if args.md:
        atomic_write_text(args.md, _markdown(rows, env, args.size))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
