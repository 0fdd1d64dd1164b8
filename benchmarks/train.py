"""Training throughput of the study's configurations, and what 300 epochs would cost.

For each model (MeshGraphNet, Transolver, Erwin: the study's hyper-parameters and batch sizes)
and each dataset size (BendVessel: 977 nodes; ClotEntry: 2048 sampled nodes) this times the
full training step as ``thrombojax train`` runs it: the device-side augmentation (random rotation
up to pi), graph construction, forward, backward and the AdamW update, on a padded batch of
synthetic samples (a bent tube of vessel nodes with a clot blob inside, scaled to [-1, 1]; the
speed depends on the node count and the neighbour cap, not on the physics). It prints compile
time, steady-state time per step, samples per second and the time of the study's 300 epochs:

* BendVessel: 17 training simulations x 39 windows = 663 samples per epoch, plus 2 generated
  per real one (BaryCentricSampling 1:2, the study's best) = 1989;
* ClotEntry: 7 training simulations x 199 windows = 1393 samples per epoch.

Usage::

    python benchmarks/train.py                      # all models, both sizes
    python benchmarks/train.py --models mgn --steps 20 --sizes 977
"""

from __future__ import annotations

import argparse
import datetime
import functools
import os
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.data.augment import AugmentConfig, augment_batch
from thrombojax.data.batching import Batch, padding_budget
from thrombojax.models.registry import create_model, get_config
from thrombojax.study import training_defaults
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import data_mesh, init_state, make_train_step, replicate, shard_batch
from thrombojax.types import NodeType, TargetStats

EPOCHS = 300
SAMPLES_PER_EPOCH = {977: ("BendVessel", 17 * 39 * 3), 2048: ("ClotEntry", 7 * 199)}


def synthetic_batch(batch_size: int, n_nodes: int, seed: int = 0) -> Batch:
    """A bent tube (vessel wall, 85 % of the nodes) with a moving clot blob, in [-1, 1]."""
    rng = np.random.default_rng(seed)
    n_clot = max(1, int(0.15 * n_nodes))
    n_vessel = n_nodes - n_clot
    budget = padding_budget(n_nodes)
    frames = np.zeros((batch_size, 3, budget, 3), np.float32)
    for b in range(batch_size):
        s = rng.uniform(0, 1, n_vessel)
        phi = rng.uniform(0, 2 * np.pi, n_vessel)
        bend = 0.5 * np.pi * s
        centre = np.stack([0.8 * np.sin(bend), 0.8 * (1 - np.cos(bend)), np.zeros_like(s)], 1)
        normal = np.stack([-np.sin(bend), np.cos(bend), np.zeros_like(s)], 1)
        wall = centre + 0.15 * (np.cos(phi)[:, None] * normal + np.sin(phi)[:, None] * [0, 0, 1])
        clot = rng.normal(0, 0.05, (n_clot, 3)) + [0.55, 0.25, 0.0]
        for f in range(3):
            frames[b, f, :n_vessel] = wall - [0.4, 0.4, 0.0]
            frames[b, f, n_vessel:n_nodes] = clot + 0.01 * f - [0.4, 0.4, 0.0]
    node_type = np.zeros((batch_size, budget), np.int32)
    node_type[:, n_vessel:n_nodes] = NodeType.CLOT
    mask = np.zeros((batch_size, budget), bool)
    mask[:, :n_nodes] = True
    return Batch(frames=frames, node_type=node_type, mask=mask,
                 generated=np.zeros(batch_size, bool))


def bench(name: str, n_nodes: int, steps: int) -> dict:
    """Compile and steady-state time of one training step of a study config."""
    config = get_config(name)
    model = create_model(name, config)
    batch_size = int(training_defaults(name)["batch_size"])
    mesh = data_mesh()
    host = synthetic_batch(batch_size, n_nodes)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 1e-3))
    tx = make_optimizer(make_schedule(training_defaults(name)["lr"], 1000, 10))
    state = replicate(init_state(model, tx, jax.random.PRNGKey(0), host), mesh)
    step = make_train_step(model, tx, stats)
    augment = jax.jit(functools.partial(augment_batch, config=AugmentConfig(max_rotation=np.pi)))
    batch = shard_batch(host, mesh)

    def run(state, i):
        key = jax.random.PRNGKey(i)
        state, metrics = step(state, augment(key, batch), key)
        return state, metrics

    t0 = time.perf_counter()
    state, metrics = run(state, 0)
    jax.block_until_ready(metrics)
    compile_s = time.perf_counter() - t0
    state, metrics = run(state, 1)  # one more warm step
    jax.block_until_ready(metrics)
    t0 = time.perf_counter()
    for i in range(steps):
        state, metrics = run(state, i + 2)
    jax.block_until_ready(metrics)
    step_s = (time.perf_counter() - t0) / steps
    dataset, per_epoch = SAMPLES_PER_EPOCH.get(n_nodes, ("custom", 1000))
    samples_per_s = batch_size / step_s
    return {
        "model": name, "dataset": dataset, "nodes": n_nodes, "batch": batch_size,
        "compile_s": compile_s, "step_ms": 1e3 * step_s, "samples_per_s": samples_per_s,
        "epoch_s": per_epoch / samples_per_s,
        "300_epochs_h": EPOCHS * per_epoch / samples_per_s / 3600,
        "loss_finite": bool(np.isfinite(float(metrics["loss"]))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--models", nargs="+", default=["mgn", "transolver", "erwin"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[977, 2048])
    parser.add_argument("--steps", type=int, default=None,
                        help="timed steps (default: 50 on an accelerator, 3 on CPU)")
    args = parser.parse_args()
    device = jax.devices()[0]
    steps = args.steps or (3 if device.platform == "cpu" else 50)
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    print(f"date: {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}")
    print(f"device: {device.device_kind} ({device.platform}) x {len(jax.devices())}; "
          f"host: {platform.node()} {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, load {load}")
    import flax
    import optax
    print(f"versions: python {platform.python_version()}, jax {jax.__version__}, "
          f"flax {flax.__version__}, optax {optax.__version__}")
    print(f"timed steps per config: {steps}; samples per epoch: BendVessel 1989 (663 real "
          "+ 1:2 generated), ClotEntry 1393")
    header = ("| model | dataset | nodes | batch | compile s | step ms | samples/s | epoch s "
              "| 300 epochs h |")
    print(header)
    print("|" + "---|" * 9)
    for name in args.models:
        for n in args.sizes:
            try:
                r = bench(name, n, steps)
            except jax.errors.JaxRuntimeError as err:  # e.g. RESOURCE_EXHAUSTED on a small host
                print(f"| {name} | {SAMPLES_PER_EPOCH.get(n, ('custom',))[0]} | {n} | - | "
                      f"failed: {str(err).splitlines()[0][:80]} |||||", flush=True)
                continue
            print(f"| {r['model']} | {r['dataset']} | {r['nodes']} | {r['batch']} | "
                  f"{r['compile_s']:.1f} | {r['step_ms']:.1f} | {r['samples_per_s']:.1f} | "
                  f"{r['epoch_s']:.1f} | {r['300_epochs_h']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
