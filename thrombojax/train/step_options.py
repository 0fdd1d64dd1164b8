"""The keyword arguments of :func:`thrombojax.train.step.make_train_step` that a training config
sets, in the compiled step's units.

One place maps :class:`thrombojax.train.config.TrainConfig` fields onto the step's options, so a
new noise or loss option is one field here and one keyword there, and the training loop
(:mod:`thrombojax.train.loop`) does not repeat the list. Noise given in vessel radii is scaled
to model coordinates with ``radius``, the vessel radius in scaled units (0 when the config uses
none of those noises).
"""

from __future__ import annotations

from typing import Any

from thrombojax.train.config import TrainConfig
from thrombojax.train.push_guards import MARGIN_R, PushGuards

__all__ = ["train_step_options"]


def train_step_options(cfg: TrainConfig, radius: float, total_steps: int) -> dict[str, Any]:
    """The options of ``make_train_step`` that ``cfg`` sets: all but model, optimiser, stats, k.

    Args:
        cfg: the training config.
        radius: the vessel radius in scaled coordinates; multiplies the noises given in radii
            (``noise_std``, ``wall_noise``, ``history_noise``) and the push-forward guards'
            distances.
        total_steps: optimiser steps of the whole run; weight averaging starts at
            ``total_steps - round(cfg.average_weights * total_steps)``.

    Returns:
        A dict of keyword arguments for :func:`thrombojax.train.step.make_train_step`.
    """
    guards = PushGuards(margin=MARGIN_R * radius, tolerance=cfg.guard_coherence * radius)
    return {
        "noise_std": cfg.noise_std * radius,
        "noise_gamma": cfg.noise_gamma,
        "noise_walk": cfg.noise_walk,
        "noise_shared": cfg.noise_shared,
        "wall_noise": cfg.wall_noise * radius,
        "history_noise": cfg.history_noise * radius,
        "speed_noise": cfg.speed_noise,
        "speed_noise_steady": cfg.speed_noise_steady,
        "direction_noise": cfg.direction_noise,
        "swell_noise": cfg.swell_noise,
        "stretch_noise": cfg.stretch_noise,
        "time_scale": cfg.time_scale,
        "pushforward": cfg.pushforward_steps,
        "clot_mean_weight": cfg.clot_mean_weight,
        "wall_loss_weight": cfg.wall_loss_weight,
        "speedup_weight": cfg.speedup_weight,
        "speedup_fraction": cfg.speedup_fraction,
        "average_from": total_steps - round(cfg.average_weights * total_steps),
        "push_guards": guards if cfg.pushforward_guards else None,
        "input_guards": guards if cfg.input_guards else None,
        "start_speed_noise": cfg.start_speed_noise,
    }
