"""Batches of training windows with one padding budget per dataset (one compiled shape).

The host side of the input pipeline, in numpy:

* :class:`WindowStore` holds the scaled trajectories of some simulations in memory and the list
  of their windows ``(simulation, t)`` of ``length`` frames (3 for single steps, ``k + 2`` for a
  k-step loss); a batch slices its windows out of the trajectories, nothing is copied per window.
* :func:`padding_budget`: every sample is padded to one node count per dataset (the nodes per
  sample, or the largest simulation), rounded up to a multiple of 64 as in flax's ogbg example,
  so ``jit`` compiles the step once; :class:`Batch` carries the masks.
* :func:`epoch_plan` shuffles the real windows and the generated (BaryCentricSampling) entries of
  one epoch, deterministically from ``(seed, epoch)``; :func:`make_batch` assembles one batch,
  subsampling nodes with a generator seeded by ``(seed, epoch, position)``. Everything a step sees
  is thus a function of the seed and the step number, which is what makes ``--resume`` exact.
* :func:`compute_target_stats`: acceleration statistics over the real clot nodes of the windows.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np
from flax import struct

from thrombojax.data.augment import subsample_indices
from thrombojax.data.scaling import Scaling
from thrombojax.data.windows import start_pair, window_times
from thrombojax.errors import ConfigError, DatasetError
from thrombojax.graph.frame import vessel_frame
from thrombojax.io.hdf5 import Dataset
from thrombojax.types import NodeType, TargetStats, clot_mask

__all__ = [
    "Batch",
    "WindowStore",
    "load_store",
    "padding_budget",
    "epoch_plan",
    "make_batch",
    "compute_target_stats",
]


@struct.dataclass
class Batch:
    """A padded batch of windows (scaled coordinates).

    Attributes:
        frames: ``[B, W, n_budget, 3]`` float32 (s_{t-1}, s_t, ..., s_{t+W-2}); padding is 0.
            Made with ``rest=True``, ``[B, 1 + W, n_budget, 3]``: the simulation's first frame
            (the clot's rest state) leads every window.
        node_type: ``[B, n_budget]`` int32 NodeType (padding: VESSEL).
        mask: ``[B, n_budget]`` bool, True on real nodes (all False for an empty padding sample).
        generated: ``[B]`` bool, True where the sample is to be replaced by BaryCentricSampling.
    """

    frames: jnp.ndarray
    node_type: jnp.ndarray
    mask: jnp.ndarray
    generated: jnp.ndarray

    @property
    def size(self) -> int:
        return self.mask.shape[0]


@dataclasses.dataclass(frozen=True)
class WindowStore:
    """Scaled trajectories of some simulations and their windows, in host memory.

    Attributes:
        names: simulation names.
        positions: per simulation ``[T, N_s, 3]`` float32 in scaled coordinates.
        node_type: per simulation ``[N_s]`` int8.
        windows: ``[n_windows, 2]`` int64 rows ``(index into names, t)``, t the window's second
            frame (the current frame of its first step).
        length: frames per window (``>= 3``).
    """

    names: tuple[str, ...]
    positions: tuple[np.ndarray, ...]
    node_type: tuple[np.ndarray, ...]
    windows: np.ndarray
    length: int = 3

    def __len__(self) -> int:
        return int(self.windows.shape[0])

    @property
    def max_nodes(self) -> int:
        return max(int(p.shape[1]) for p in self.positions)


def load_store(
    dataset: Dataset, names: Sequence[str], scaling: Scaling, *, skip: int = 0, length: int = 3
) -> WindowStore:
    """Read simulations into memory, scaled, and list their windows.

    Args:
        dataset: an open :class:`thrombojax.io.hdf5.Dataset`.
        names: simulation names to load.
        scaling: the dataset's :class:`thrombojax.data.scaling.Scaling`.
        skip: first frames not used as the frame t (``window_times(..., skip=skip)``).
        length: frames per window (3: single step; ``k + 2`` for a k-step loss;
            :attr:`thrombojax.train.config.TrainConfig.window_length` in general).
    Returns:
        The :class:`WindowStore`.
    """
    positions, types, rows = [], [], []
    for i, name in enumerate(names):
        pos = np.asarray(dataset.positions(name), np.float64)
        positions.append(np.asarray(scaling.apply(pos), np.float32))
        types.append(np.asarray(dataset.node_type(name), np.int8))
        times = window_times(pos.shape[0], skip=skip, length=length)
        rows.extend((i, int(t)) for t in times)
    if not rows:
        raise DatasetError(
            f"{getattr(dataset, 'path', '<dataset>')}: simulations {list(names)}: field "
            f"'positions': no windows of {length} frames with skip={skip}"
        )
    windows = np.asarray(rows, np.int64).reshape(-1, 2)
    return WindowStore(tuple(names), tuple(positions), tuple(types), windows, int(length))


def padding_budget(max_nodes: int, nodes_per_sample: int | None = None, multiple: int = 64) -> int:
    """The node budget of every sample: ``min(nodes_per_sample, max_nodes)`` rounded up.

    Args:
        max_nodes: nodes of the largest simulation.
        nodes_per_sample: subsample size (``None``: all nodes).
        multiple: round up to a multiple of this.
    Returns:
        The padded node count.
    """
    n = max_nodes if nodes_per_sample is None else min(int(nodes_per_sample), max_nodes)
    return int(-(-n // multiple) * multiple)


def epoch_plan(
    n_windows: int, *, bary_ratio: float, batch_size: int, seed: int, epoch: int
) -> np.ndarray:
    """The shuffled entries of one epoch, grouped in batches.

    Each real window appears once; ``round(bary_ratio * n_windows)`` generated entries (each on a
    source window, cycling through a permutation) are added, i.e. real:generated = 1:bary_ratio.
    The last batch is filled with empty entries (window -1).

    Args:
        n_windows: number of real training windows.
        bary_ratio: generated samples per real sample (the study's best: 2, i.e. 1:2).
        batch_size: samples per batch.
        seed, epoch: the plan is a pure function of these.
    Returns:
        ``[n_batches, batch_size, 2]`` int64: (window index or -1, generated flag).
    """
    if batch_size < 1:
        raise ConfigError(f"batch size must be >= 1, got {batch_size}")
    if bary_ratio < 0:
        raise ConfigError(f"bary_ratio must be >= 0, got {bary_ratio}")
    rng = np.random.default_rng([int(seed), int(epoch), 17])
    n_gen = int(round(bary_ratio * n_windows))
    real = np.stack([np.arange(n_windows), np.zeros(n_windows, np.int64)], axis=1)
    source = np.resize(rng.permutation(n_windows), n_gen) if n_gen else np.zeros(0, np.int64)
    gen = np.stack([source, np.ones(n_gen, np.int64)], axis=1)
    entries = np.concatenate([real, gen])[rng.permutation(n_windows + n_gen)]
    n_batches = -(-entries.shape[0] // batch_size)
    pad = n_batches * batch_size - entries.shape[0]
    entries = np.concatenate([entries, np.tile([[-1, 0]], (pad, 1))]).astype(np.int64)
    return entries.reshape(n_batches, batch_size, 2)


def make_batch(
    store: WindowStore,
    entries: np.ndarray,
    budget: int,
    *,
    nodes_per_sample: int | None = None,
    seed: int = 0,
    epoch: int = 0,
    position: int = 0,
    rest: bool = False,
    start_speed: tuple[int, ...] | None = None,
) -> Batch:
    """Assemble one padded batch on the host.

    Args:
        store: the windows.
        entries: ``[B, 2]`` rows of :func:`epoch_plan` (window index or -1, generated flag).
        budget: node budget (:func:`padding_budget`).
        nodes_per_sample: subsample this many nodes per sample (clot fraction kept).
        seed, epoch, position: the subsampling of sample ``b`` is seeded with
            ``(seed, epoch, position, b)``.
        rest: every window is led by its simulation's first frame, the clot's rest state (same
            nodes; for a learned step with ``rest_edges``).
        start_speed: ``(start, history[, span])`` for a learned step with ``start_speed``: the
            window (its frame t at ``t_w = first + history``) is led, after the rest frame, by
            the frames ``max(c - span, 0), c`` with ``c = max(min(t_w, start), 1)``, ``start`` the
            frame the dataset's rollouts start from, ``span`` 1 by default
            (:mod:`thrombojax.simulator.start_speed`).
    Returns:
        A :class:`Batch` of numpy arrays.
    """
    size = entries.shape[0]
    length, lead = store.length, int(rest) + 2 * (start_speed is not None)
    frames = np.zeros((size, lead + length, budget, 3), np.float32)
    node_type = np.full((size, budget), int(NodeType.VESSEL), np.int32)
    mask = np.zeros((size, budget), bool)
    for b, window in enumerate(entries[:, 0]):
        if window < 0:
            continue
        sim, t = store.windows[window]
        types = store.node_type[sim]
        idx = np.arange(types.shape[0])
        if nodes_per_sample is not None:
            rng = np.random.default_rng([int(seed), int(epoch), int(position), b, 29])
            idx = subsample_indices(rng, types, nodes_per_sample)
        if idx.shape[0] > budget:
            raise ConfigError(
                f"simulation '{store.names[sim]}' has {idx.shape[0]} nodes per sample, more than "
                f"the padding budget {budget}"
            )
        n = idx.shape[0]
        frames[b, lead:, :n] = store.positions[sim][t - 1 : t - 1 + length][:, idx]
        if rest:
            frames[b, 0, :n] = store.positions[sim][0, idx]
        if start_speed is not None:
            pair = start_pair(t - 1 + int(start_speed[1]), start_speed[0], *start_speed[2:])
            frames[b, int(rest):int(rest) + 2, :n] = store.positions[sim][list(pair)][:, idx]
        node_type[b, :n] = types[idx]
        mask[b, :n] = True
    return Batch(frames=frames, node_type=node_type, mask=mask, generated=entries[:, 1] > 0)


def compute_target_stats(
    store: WindowStore, *, isotropic: bool = False, frame: str = "global",
    min_std: float = 1e-8,
) -> TargetStats:
    """Statistics of ``a_t = s_{t+1} - 2 s_t + s_{t-1}`` over the clot nodes of every window.

    Computed over the store (the training split, all nodes, no augmentation) in float64.

    * ``isotropic=False``: per-axis mean and standard deviation.
    * ``isotropic=True`` (training with random rotations): rotation-invariant statistics, mean 0
      and one RMS ``sqrt(E|a|^2 / 3)`` for all axes. Per-axis statistics would be wrong for
      rotated samples: a clot moving in a plane has a near-zero standard deviation along the
      plane's normal, and a rotated sample's acceleration along that axis would be blown up.

    * ``frame="vessel"``: the statistics of the acceleration expressed in each simulation's
      vessel frame (:func:`thrombojax.graph.frame.vessel_frame`), what a learned step in that
      frame predicts. Training combines it with ``isotropic=True``: in that frame the clot of
      a planar vessel barely moves along the plane's normal, and per-axis statistics would
      weight the loss by the inverse square of that tiny spread.

    ``velocity_std`` is the isotropic RMS ``sqrt(E|v|^2 / 3)`` of ``v_t = s_t - s_{t-1}`` over
    the same clot nodes (one number for all axes, so it is rotation-invariant).

    A standard deviation below ``min_std`` is raised to it.

    Returns:
        :class:`TargetStats` with ``mean [3]``, ``std [3]``, ``velocity_std []``.
    """
    total = np.zeros(3)
    total_sq = np.zeros(3)
    vel_sq = 0.0
    count = 0
    for sim, pos in enumerate(store.positions):
        times = store.windows[store.windows[:, 0] == sim, 1]
        if times.size == 0:
            continue
        clot = clot_mask(store.node_type[sim])
        p = pos[:, clot].astype(np.float64)
        if frame == "vessel":
            axes = np.asarray(vessel_frame(pos[0], store.node_type[sim]).axes, np.float64)
            p = p @ axes
        accel = p[times + 1] - 2.0 * p[times] + p[times - 1]
        total += accel.sum(axis=(0, 1))
        total_sq += (accel**2).sum(axis=(0, 1))
        vel_sq += float(((p[times] - p[times - 1]) ** 2).sum())
        count += accel.shape[0] * accel.shape[1]
    if count == 0:
        raise DatasetError(f"simulations {list(store.names)}: field 'node_type': no clot nodes")
    mean = total / count
    std = np.sqrt(np.maximum(total_sq / count - mean**2, 0.0))
    if isotropic:
        mean = np.zeros(3)
        std = np.full(3, np.sqrt(total_sq.sum() / count / 3.0))
    std = np.maximum(std, min_std)
    velocity_std = max(np.sqrt(vel_sq / count / 3.0), min_std)
    return TargetStats(
        mean=jnp.asarray(mean, jnp.float32),
        std=jnp.asarray(std, jnp.float32),
        velocity_std=jnp.asarray(velocity_std, jnp.float32),
    )
