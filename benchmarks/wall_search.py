"""The dense wall searches before and after their rewrite, in one run: the same answers, faster.

Every learned step with wall or vessel-axis inputs searches the frame densely (``N x N``):

* :func:`thrombojax.graph.wall_nodes.wall_patches`, the 12 nearest vessel nodes of every node
  (the wall normals behind the vessel axis, the prior and the signed wall features). Before:
  ``lax.top_k`` over all ``N`` columns, a single-threaded partial sort on the CPU. After:
  :func:`~thrombojax.graph.wall_nodes.smallest_first`, ``top_k`` over block minima and then
  over the 12 blocks kept, exact.
* :func:`thrombojax.graph.wall_nodes.nearest_vessel_node`, behind the wall features. Before:
  ``jnp.argmin``, one (value, index) reduction that XLA's CPU code does not vectorise. After:
  :func:`~thrombojax.graph.wall_nodes.first_min`, the minimum and then the lowest column holding
  it, the same index.

Part 1 times each pair alone on the synthetic tube of ``benchmarks/models.py`` (a batch of
``--batch`` frames, as a training step sees them, vmapped) and checks that the answers are equal
element for element. Part 2 (with ``--dataset`` and ``--config``, e.g. a ClotEntry file and a run's
``config.json``) times the real training step of that recipe: ``thrombojax.train.loop.train`` in
a fresh process per variant, the first ``--warm`` steps dropped, rounds alternating before and
after; the before-variant puts the old calls back in :mod:`thrombojax.graph.wall_nodes`. The
losses of the two variants must be bit for bit the same (checked, printed). The header records
device, versions, date and load.

Usage::

    python benchmarks/wall_search.py [--nodes 977 2048 4096] [--batch 4] [--repeats 10]
        [--dataset data/clotentry.h5 --config RUN/config.json --steps 25 --warm 5 --rounds 2]
        [--out results.json] [--md results.md]
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from models import _median_ms, synthetic_inputs  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.graph import wall_nodes  # noqa: E402
from thrombojax.io.outputs import atomic_write_text, refuse_targets  # noqa: E402


def _old_smallest_first(key, k):
    return jax.lax.top_k(-key, k)[1]


def _old_first_min(d):
    return jnp.argmin(d, axis=1).astype(jnp.int32)


VARIANTS = {"before": (_old_smallest_first, _old_first_min),
            "after": (wall_nodes.smallest_first, wall_nodes.first_min)}


def _use(variant: str) -> None:
    """Put the variant's two calls in :mod:`thrombojax.graph.wall_nodes` (looked up when traced)."""
    wall_nodes.smallest_first, wall_nodes.first_min = VARIANTS[variant]


def bench_functions(n_nodes: int, *, batch: int, repeats: int, layout: str) -> list[dict]:
    """Part 1: both searches before and after at ``n_nodes`` nodes, ``batch`` frames vmapped,
    the nodes numbered at random (``layout="random"``) or along the tube (``"along"``)."""
    frames = [synthetic_inputs(n_nodes, seed=s) for s in range(batch)]
    x = np.stack([np.asarray(f.positions) for f in frames])
    node_type = np.stack([np.asarray(f.node_type) for f in frames])
    if layout == "along":  # numbered along the tube, as a mesh's rings are
        order = np.argsort(x[..., 0], axis=1, kind="stable")
        x = np.take_along_axis(x, order[..., None], axis=1)
        node_type = np.take_along_axis(node_type, order, axis=1)
    x, node_type = jnp.asarray(x), jnp.asarray(node_type)
    mask = jnp.ones(node_type.shape, bool)
    rows, answers = [], {}
    for what, fn in (("wall_patches", wall_nodes.wall_patches),
                     ("nearest_vessel_node", wall_nodes.nearest_vessel_node)):
        for variant in VARIANTS:
            _use(variant)
            call = jax.jit(jax.vmap(lambda *a, f=fn: f(*a)))  # fresh: traced per variant
            answers[variant] = np.asarray(call(x, node_type, mask))
            ms = round(_median_ms(call, x, node_type, mask, repeats=repeats), 1)
            rows.append({"what": what, "variant": variant, "nodes": n_nodes, "batch": batch,
                         "layout": layout, "ms": ms})
        _use("after")
        rows[-1]["speedup"] = round(rows[-2]["ms"] / rows[-1]["ms"], 2)
        rows[-1]["equal"] = bool(np.array_equal(answers["before"], answers["after"]))
        if not rows[-1]["equal"]:
            raise SystemExit(f"{what}: the two variants differ at {n_nodes} nodes")
    return rows


def _worker(variant: str, dataset: str, config: str, steps: int, warm: int) -> None:
    """One training run of ``steps`` steps: prints its step times and losses as one JSON line."""
    from thrombojax.train.loop import train

    _use(variant)
    stamps, losses = [], []

    class Stop(Exception):
        pass

    def callback(step, metrics):
        stamps.append(time.perf_counter())
        losses.append(float(metrics["loss"]))
        if len(stamps) >= steps:
            raise Stop

    with tempfile.TemporaryDirectory() as out:
        try:
            train(dataset, None, os.path.join(out, "run"), config=config, progress=False,
                  callback=callback)
        except Stop:
            pass
    print(json.dumps({"step_s": np.diff(stamps[warm:]).tolist(), "loss": losses}), flush=True)


def bench_training(dataset: str, config: str, *, steps: int, warm: int, rounds: int) -> dict:
    """Part 2: the recipe's training step, before and after, ``rounds`` alternating runs each."""
    times = {v: [] for v in VARIANTS}
    losses = {}
    for _ in range(rounds):
        for variant in VARIANTS:
            out = subprocess.run([sys.executable, __file__, "--worker", variant, "--dataset",
                                  dataset, "--config", config, "--steps", str(steps), "--warm",
                                  str(warm)], check=True, capture_output=True, text=True).stdout
            got = json.loads(out.strip().splitlines()[-1])
            times[variant] += got["step_s"]
            losses.setdefault(variant, got["loss"])
    same = losses["before"] == losses["after"]
    if not same:
        raise SystemExit("the training losses differ between the variants")
    med = {v: statistics.median(t) for v, t in times.items()}
    return {"dataset": dataset, "config": config, "steps_timed": {v: len(t) for v, t in
            times.items()}, "median_step_s": {v: round(m, 4) for v, m in med.items()},
            "speedup": round(med["before"] / med["after"], 3), "losses_identical": same}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--nodes", type=int, nargs="+", default=[977, 2048, 4096])
    p.add_argument("--batch", type=int, default=4, help="frames per call (a training batch)")
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--layouts", nargs="+", choices=["random", "along"],
                   default=["random", "along"],
                   help="node numbering of the synthetic tube: at random, or along the tube "
                        "(as a mesh numbers its rings; lax.top_k's cost depends on it)")
    p.add_argument("--dataset", help="with --config: also time that recipe's training step")
    p.add_argument("--config", help="a run's config.json (the recipe to time)")
    p.add_argument("--steps", type=int, default=25, help="training steps per run")
    p.add_argument("--warm", type=int, default=5, help="first steps of a run not timed")
    p.add_argument("--rounds", type=int, default=2, help="runs per variant, alternating")
    p.add_argument("--out", help="JSON file to write (refused if it exists, unless --force)")
    p.add_argument("--md", help="markdown table to write (refused if it exists, unless --force)")
    p.add_argument("--force", action="store_true", help="replace an existing --out/--md")
    p.add_argument("--worker", choices=sorted(VARIANTS), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if bool(a.dataset) != bool(a.config):
        p.error("--dataset and --config go together")
    refuse_targets(p, (a.out, a.md), force=a.force, what="report")
    if a.worker:
        _worker(a.worker, a.dataset, a.config, a.steps, a.warm)
        return 0
    rows = [r for n in a.nodes for lay in a.layouts
            for r in bench_functions(n, batch=a.batch, repeats=a.repeats, layout=lay)]
    training = (bench_training(a.dataset, a.config, steps=a.steps, warm=a.warm,
                               rounds=a.rounds) if a.dataset else None)
    result = {"environment": environment(), "functions": rows, "training": training}
    lines = ["# The dense wall searches before and after (synthetic tube, vmapped batch)", "",
             "| search | nodes | numbered | batch | before ms | after ms | speed-up | equal |",
             "|---|---|---|---|---|---|---|---|"]
    for before, after in zip(rows[::2], rows[1::2], strict=True):
        lines.append(f"| {after['what']} | {after['nodes']} | {after['layout']} | "
                     f"{after['batch']} | {before['ms']} | {after['ms']} | {after['speedup']}x | "
                     f"{after['equal']} |")
    if training:
        m = training["median_step_s"]
        lines += ["", f"Training step of `{training['config']}` on `{training['dataset']}` "
                  f"(median over {training['steps_timed']['after']} steps per variant): before "
                  f"{m['before']} s, after {m['after']} s, {training['speedup']}x; losses "
                  f"identical: {training['losses_identical']}."]
    lines += ["", *[f"- {k}: {v}" for k, v in result["environment"].items()]]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        atomic_write_text(a.out, json.dumps(result, indent=1) + "\n")
    if a.md:
        atomic_write_text(a.md, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
