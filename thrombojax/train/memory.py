"""Memory that a training configuration asks for, estimated before any work (issue 14).

``--bary-ratio 1e9`` once ran the machine out of memory at 20.8 GB with no message. The flags
that scale memory, and what they scale (``thrombojax/train/loop.py``):

* ``--bary-ratio`` (``bary_ratio``): the epoch plan of :func:`thrombojax.data.batching.epoch_plan`
  holds ``n_windows * (1 + bary_ratio)`` entries of two int64; building it peaks at 72 bytes
  per entry (measured with ``tracemalloc``: ``tests/test_train_memory.py``), plus the previous
  epoch's plan (16 bytes per entry); :data:`PLAN_BYTES_PER_ENTRY` rounds the sum up.
* ``--batch-size`` and ``--nodes-per-sample`` (``batch_size``, ``nodes_per_sample``): every batch
  of :func:`thrombojax.data.batching.make_batch` is ``batch x length x budget x 3`` float32 plus
  the node types and mask; the loop holds every validation batch, the training batch, and its
  device copy and augmented copy.
* ``bary_max_neighbors``: BaryCentricSampling's triangle search
  (:func:`thrombojax.data.augment.find_sample_triangles`) examines the ``K (K - 1) / 2``
  neighbour pairs of every node of every sample; :data:`PAIR_BYTES` bytes per pair bound what
  XLA allocates for :func:`thrombojax.data.augment.augment_batch` (checked against the
  compiler's memory analysis in ``tests/test_train_memory.py``).

Each component bounds its own buffers from above (within a factor of about 1.6 for the triangle
search, exact for the plan and batches). The model's own activations are not counted (they
depend on the model, not on these flags), so a run refused here could not fit; one accepted may
still need more for the model.
"""

from __future__ import annotations

import math
import os

from thrombojax.errors import ConfigError

__all__ = [
    "PLAN_BYTES_PER_ENTRY",
    "PAIR_BYTES",
    "available_memory",
    "estimate_train_memory",
    "check_train_memory",
]

PLAN_BYTES_PER_ENTRY = 80 + 16  # one plan's peak (72 measured), plus the previous epoch's plan
PAIR_BYTES = 48  # per neighbour pair of the triangle search (triangle, its types, flags)
_NODE_BYTES = 64  # per neighbour-list slot (radius graph indices, distances, masks)
_NODE_FIXED = 1024  # per node (cell grid / dense search buffers, coefficients, vertices)

# component -> the option that scales it, for the message
_OPTION = {
    "epoch plan": "--bary-ratio (bary_ratio)",
    "batches": "--batch-size / --nodes-per-sample (batch_size, nodes_per_sample)",
    "triangle search": "bary_max_neighbors (--config)",
}


def available_memory() -> int | None:
    """Physical memory of this machine in bytes (``None`` where the OS does not say)."""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return int(pages) * int(size) if pages > 0 and size > 0 else None


def estimate_train_memory(
    *, n_windows: int, n_val_windows: int, bary_ratio: float, batch_size: int, budget: int,
    length: int, max_neighbors: int,
) -> dict[str, int]:
    """Bytes that the training loop's flag-dependent buffers take, by component.

    Args:
        n_windows: training windows (real samples per epoch).
        n_val_windows: validation windows.
        bary_ratio: generated samples per real one (0: no BaryCentricSampling).
        batch_size: samples per step.
        budget: padded nodes per sample (:func:`thrombojax.data.batching.padding_budget`).
        length: frames per window.
        max_neighbors: ``bary_max_neighbors``, the neighbour cap of the triangle search.
    Returns:
        ``{"epoch plan": bytes, "batches": bytes, "triangle search": bytes}``.
    """
    entries = n_windows + round(bary_ratio * n_windows)
    entries = math.ceil(entries / batch_size) * batch_size
    one_batch = batch_size * (length * budget * 3 * 4 + budget * (4 + 1) + 1)
    n_batches = math.ceil(n_val_windows / batch_size) + 3  # validation, host, device, augmented
    pairs = max_neighbors * (max_neighbors - 1) // 2
    triangles = (batch_size * budget * (PAIR_BYTES * pairs + _NODE_BYTES * max_neighbors
                                        + _NODE_FIXED) if bary_ratio > 0 else 0)
    return {"epoch plan": int(PLAN_BYTES_PER_ENTRY * entries),
            "batches": int(n_batches * one_batch), "triangle search": int(triangles)}


def _size(n: float) -> str:
    """``9.6e9`` -> ``'9.6 GB'``; ``126`` -> ``'126 B'``."""
    for unit, name in ((1e12, "TB"), (1e9, "GB"), (1e6, "MB"), (1e3, "kB")):
        if n >= unit:
            return f"{n / unit:.3g} {name}"
    return f"{n:.0f} B"


def check_train_memory(
    estimate: dict[str, int], *, values: dict[str, object], where: str = "",
    available: int | None = None,
) -> None:
    """Refuse a configuration whose estimate exceeds the machine's memory.

    Args:
        estimate: :func:`estimate_train_memory`.
        values: the option values to quote (e.g. ``{"bary_ratio": 1e9}``).
        where: what the message starts with (the dataset file; empty: nothing).
        available: bytes available (default :func:`available_memory`; ``None``: no check).
    Raises:
        ConfigError: one line naming the option of the largest component, its value, the
            estimated total and the available memory.
    """
    available = available_memory() if available is None else available
    total = sum(estimate.values())
    if available is None or total <= available:
        return
    worst = max(estimate, key=estimate.get)
    quoted = ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
                       for k, v in values.items())
    parts = ", ".join(f"{k} {_size(v)}" for k, v in estimate.items() if v)
    prefix = f"{where}: " if where else ""
    raise ConfigError(f"{prefix}{_OPTION[worst]} asks for more memory than this machine has: "
                      f"about {_size(total)} ({parts}) for {quoted}; available "
                      f"{_size(available)}")
