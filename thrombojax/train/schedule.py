"""Learning-rate schedule and optimiser: AdamW, linear warm-up then cosine decay, per step.

The study (thesis Appendix, "Linear Warmup + Cosine Decay"): 10 warm-up epochs out of 300, then a
cosine decay. We apply the schedule per optimiser step (warm-up steps = warm-up epochs x steps per
epoch), the learning rate rising linearly from 0 to its peak and decaying to 0 at the last step
(``optax.warmup_cosine_decay_schedule``). AdamW's weight decay defaults to PyTorch's 0.01, the
library the study trained with; gradient clipping by global norm is optional (off by default,
the study did not mention any).
"""

from __future__ import annotations

import optax

from thrombojax.errors import ConfigError

__all__ = ["make_schedule", "make_optimizer"]


def make_schedule(peak_lr: float, total_steps: int, warmup_steps: int) -> optax.Schedule:
    """Linear warm-up from 0 to ``peak_lr`` over ``warmup_steps``, then cosine decay to 0.

    Args:
        peak_lr: the peak learning rate (the study's "learning rate").
        total_steps: the number of optimiser steps of the whole run (>= 1).
        warmup_steps: warm-up steps, clipped to ``[0, total_steps - 1]``.
    Returns:
        An optax schedule ``step -> learning rate``.
    """
    if total_steps < 1:
        raise ConfigError(f"total number of training steps must be >= 1, got {total_steps}")
    if peak_lr <= 0:
        raise ConfigError(f"learning rate must be positive, got {peak_lr}")
    warmup = max(0, min(int(warmup_steps), total_steps - 1))
    return optax.warmup_cosine_decay_schedule(
        init_value=0.0,
        peak_value=float(peak_lr),
        warmup_steps=warmup,
        decay_steps=int(total_steps),
        end_value=0.0,
    )


def make_optimizer(
    schedule: optax.Schedule | float,
    *,
    weight_decay: float = 0.01,
    grad_clip: float | None = None,
) -> optax.GradientTransformation:
    """AdamW with an optional global-norm gradient clip in front.

    Args:
        schedule: learning-rate schedule (or a constant).
        weight_decay: decoupled weight decay (PyTorch's AdamW default 0.01).
        grad_clip: clip gradients to this global norm; ``None`` or ``<= 0`` disables it.
    Returns:
        The optax transformation.
    """
    adamw = optax.adamw(schedule, weight_decay=weight_decay)
    if grad_clip is not None and grad_clip > 0:
        return optax.chain(optax.clip_by_global_norm(grad_clip), adamw)
    return adamw
