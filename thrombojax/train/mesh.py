"""The device mesh of data-parallel training: one axis ``"data"`` that the batch is split along.

:func:`data_mesh` builds the mesh over the local devices (or all devices of all hosts after
``jax.distributed.initialize()``), :func:`shard_batch` places a host batch on it split along its
leading axis and :func:`replicate` puts a pytree (the train state) on every device. The jitted
training step (:mod:`thrombojax.train.step`, which re-exports these) then follows the data.
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

__all__ = ["data_mesh", "shard_batch", "replicate"]


def data_mesh(devices: list | None = None) -> Mesh:
    """A 1-D device mesh with the axis ``"data"`` (default: every device, all hosts)."""
    devices = jax.devices() if devices is None else list(devices)
    return Mesh(np.asarray(devices), ("data",))


def shard_batch(batch: Any, mesh: Mesh) -> Any:
    """Put a host batch on the mesh, split along its leading (batch) axis.

    Every host passes the same full batch; each device receives its slice.
    """
    sharding = NamedSharding(mesh, P("data"))

    def put(x):
        x = np.asarray(x)
        return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])

    return jax.tree.map(put, batch)


def replicate(tree: Any, mesh: Mesh) -> Any:
    """Place a pytree on every device of the mesh (``PartitionSpec()``)."""
    sharding = NamedSharding(mesh, P())
    return jax.tree.map(lambda x: jax.device_put(x, sharding), tree)
