"""Data parallelism: 4 (fake CPU) devices give the loss and gradients of one device."""

import json
import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import json
    import jax, jax.numpy as jnp, numpy as np
    from thrombojax.data.batching import Batch
    from thrombojax.models.registry import create_model, get_config
    from thrombojax.train.schedule import make_optimizer
    from thrombojax.train.step import (batch_loss, data_mesh, init_state, make_train_step,
                                       replicate, shard_batch)
    from thrombojax.types import TargetStats

    assert len(jax.devices()) == 4, jax.devices()
    rng = np.random.default_rng(0)
    B, N = 8, 48
    frames = rng.normal(0, 0.3, (B, 3, N, 3)).astype(np.float32)
    frames[:, :, :30] = frames[:, 1:2, :30]  # vessel nodes do not move
    node_type = np.zeros((B, N), np.int32); node_type[:, 30:44] = 1
    mask = np.ones((B, N), bool); mask[:, 44:] = False; mask[5, 20:] = False
    batch = Batch(frames=frames, node_type=node_type, mask=mask, generated=np.zeros(B, bool))
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.full(3, 0.3))
    model = create_model("mgn", get_config("mgn", tiny=True))
    tx = make_optimizer(1e-3)
    state = init_state(model, tx, jax.random.PRNGKey(0), batch)
    key = jax.random.PRNGKey(1)

    def loss_grads(mesh):
        params = replicate(state.params, mesh)
        b = shard_batch(batch, mesh)
        fn = jax.jit(jax.value_and_grad(
            lambda p, bb: batch_loss(model, p, stats, bb, key, train=True)[0]))
        loss, grads = fn(params, b)
        step = make_train_step(model, tx, stats, donate=False)
        new, metrics = step(replicate(state, mesh), b, key)
        host = jax.tree.map(np.asarray, (loss, grads, new.params, metrics))
        return (*host, b)

    out = {}
    l1, g1, p1, m1, _ = loss_grads(data_mesh(jax.devices()[:1]))
    l4, g4, p4, m4, b4 = loss_grads(data_mesh())
    out["n_shards"] = len(b4.frames.sharding.device_set)
    out["loss"] = [float(l1), float(l4)]
    out["metric_loss"] = [float(m1["loss"]), float(m4["loss"])]
    diff = jax.tree.map(lambda a, b: float(np.max(np.abs(a - b))), g1, g4)
    scale = jax.tree.map(lambda a: float(np.max(np.abs(a))), g1)
    out["grad_diff"] = max(jax.tree.leaves(diff))
    out["grad_scale"] = max(jax.tree.leaves(scale))
    pdiff = jax.tree.map(lambda a, b: float(np.max(np.abs(a - b))), p1, p4)
    out["param_diff"] = max(jax.tree.leaves(pdiff))
    print("RESULT" + json.dumps(out))
    """
)


def test_four_devices_match_one(tmp_path):
    env = dict(os.environ)
    env["XLA_FLAGS"] = env.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    env["JAX_PLATFORMS"] = "cpu"
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT")][-1]
    res = json.loads(line[len("RESULT"):])
    assert res["n_shards"] == 4  # the batch really is split over four devices
    l1, l4 = res["loss"]
    assert abs(l1 - l4) <= 1e-5 * abs(l1)
    assert res["metric_loss"][0] == l1 or abs(res["metric_loss"][0] - l1) <= 1e-5 * abs(l1)
    assert abs(res["metric_loss"][1] - l4) <= 1e-5 * abs(l4)
    assert res["grad_scale"] > 0
    assert res["grad_diff"] <= 1e-5 * res["grad_scale"] + 1e-7
    assert res["param_diff"] <= 1e-6
