"""Value checks of a training configuration: types, finiteness and ranges of every field.

:func:`check_train_values` runs when a :class:`~thrombojax.train.config.TrainConfig` is built
(from flags, a ``--config`` JSON file or a run's ``config.json``), so a wrongly typed JSON value,
``--max-rotation nan``, a negative warm-up, noise, checkpoint interval or frame skip is one
:class:`~thrombojax.errors.ConfigError` naming the option, before any data is read.
"""

from __future__ import annotations

import math
from typing import Any

from thrombojax.errors import ConfigError
from thrombojax.train.memory import check_train_memory, estimate_train_memory

__all__ = ["check_train_values", "uses_vessel_radius"]

# field -> (kind, lower bound, bound inclusive, may be None)
_RULES: dict[str, tuple[str, float, bool, bool]] = {
    "epochs": ("int", 1, True, False),
    "batch_size": ("int", 1, True, True),
    "lr": ("float", 0.0, False, True),
    "warmup_epochs": ("float", 0.0, True, False),
    "weight_decay": ("float", 0.0, True, False),
    "grad_clip": ("float", 0.0, False, True),
    "radius": ("float", 0.0, False, True),
    "max_rotation": ("float", 0.0, True, False),
    "nodes_per_sample": ("int", 1, True, True),
    "bary_ratio": ("float", 0.0, True, False),
    "bary_radius": ("float", 0.0, False, True),
    "bary_max_neighbors": ("int", 2, True, False),
    "noise_std": ("float", 0.0, True, False),
    "wall_features": ("float", 0.0, True, False),
    "axis_features": ("float", 0.0, True, False),
    "follow_axis": ("float", 0.0, True, False),
    "lateral_hold": ("float", 0.0, True, False),
    "outlet_features": ("float", 0.0, True, False),
    "shape_features": ("float", 0.0, True, False),
    "clearance_features": ("float", 0.0, True, False),
    "section_features": ("float", 0.0, True, False),
    "centre_pull": ("float", 0.0, True, False),
    "centre_tolerance": ("float", 0.0, True, False),
    "noise_gamma": ("float", 0.0, True, False),
    "noise_shared": ("float", 0.0, True, False),
    "wall_noise": ("float", 0.0, True, False),
    "history_noise": ("float", 0.0, True, False),
    "speed_noise": ("float", 0.0, True, False),
    "speed_noise_steady": ("float", 0.0, True, False),
    "start_speed_noise": ("float", 0.0, True, False),
    "direction_noise": ("float", 0.0, True, False),
    "swell_noise": ("float", 0.0, True, False),
    "stretch_noise": ("float", 0.0, True, False),
    "time_scale": ("float", 1.0, True, False),
    "clot_mean_weight": ("float", 0.0, True, False),
    "wall_loss_weight": ("float", 0.0, True, False),
    "speedup_weight": ("float", 0.0, True, False),
    "speedup_fraction": ("float", 0.0, True, False),
    "average_weights": ("float", 0.0, True, False),
    "seed": ("int", 0, True, False),
    "split_seed": ("int", 0, True, False),
    "n_val": ("int", 0, True, False),
    "n_test": ("int", 0, True, False),
    "skip_frames": ("int", 0, True, False),
    "checkpoint_every": ("int", 0, True, False),
    "rollout_steps": ("int", 1, True, False),
    "pushforward_steps": ("int", 0, True, False),
    "guard_coherence": ("float", 0.0, True, False),
    "curriculum_epochs": ("float", 0.0, True, False),
    "history": ("int", 1, True, False),
    "start_span": ("int", 1, True, False),
}


_HIGH: dict[str, float] = {"noise_shared": 1.0, "average_weights": 1.0, "centre_pull": 1.0}
"""Inclusive upper bounds of the fields that have one (``noise_shared``: a share of a variance;
``average_weights``: a share of the training steps)."""


def _option(name: str) -> str:
    return "--" + name.replace("_", "-")


def _check_one(name: str, value: Any) -> None:
    kind, low, inclusive, optional = _RULES[name]
    if value is None:
        if optional:
            return
        raise ConfigError(f"{_option(name)} ({name}) must be a number, got null")
    if isinstance(value, bool) or not isinstance(value, int | float):
        noun = "an integer" if kind == "int" else "a number"
        raise ConfigError(f"{_option(name)} ({name}) must be {noun}, got "
                          f"{type(value).__name__} {value!r}")
    if kind == "int" and not float(value).is_integer():
        raise ConfigError(f"{_option(name)} ({name}) must be an integer, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"{_option(name)} ({name}) must be finite, got {value!r}")
    if value < low or (value == low and not inclusive):
        sign = ">=" if inclusive else ">"
        raise ConfigError(f"{_option(name)} ({name}) must be {sign} {low:g}, got {value!r}")
    if name in _HIGH and value > _HIGH[name]:
        raise ConfigError(f"{_option(name)} ({name}) must be <= {_HIGH[name]:g}, got {value!r}")


def check_train_values(cfg: Any) -> None:
    """Check every field of a TrainConfig; raises :class:`ConfigError` naming the option.

    Also: the memory ``bary_ratio`` asks for even on one window
    (:func:`thrombojax.train.memory.check_train_memory`; the training loop checks again with the
    dataset's sizes), ``tiny``, ``noise_walk``, ``stop_history_gradient``,
    ``uniform_rotation``, ``rest_edges``, ``start_speed`` (not with the guards of the
    training; ``start_speed_noise`` and ``start_span`` only with it), ``input_guards``,
    ``pushforward_guards`` (only with ``pushforward_steps``) and ``wall_signed`` booleans
    (``wall_signed`` only with ``wall_features``), ``history_noise`` only with ``history >= 2``,
    ``model_config`` an object; upper bounds in :data:`_HIGH`.
    """
    for name in _RULES:
        if name == "centre_tolerance" and getattr(cfg, name, None) == "auto":
            continue  # fitted on the training simulations (thrombojax.train.centre_fit)
        if hasattr(cfg, name):
            _check_one(name, getattr(cfg, name))
    check_train_memory(estimate_train_memory(  # one window of one node: a lower bound
        n_windows=1, n_val_windows=0, bary_ratio=cfg.bary_ratio, batch_size=cfg.batch_size or 1,
        budget=1, length=3, max_neighbors=cfg.bary_max_neighbors,
    ), values={"bary_ratio": float(cfg.bary_ratio), "bary_max_neighbors": cfg.bary_max_neighbors})
    for flag in ("tiny", "noise_walk", "stop_history_gradient", "wall_signed", "wall_clot_mean",
                 "uniform_rotation", "rest_edges", "pushforward_guards",
                 "input_guards", "start_speed"):
        if not isinstance(getattr(cfg, flag, False), bool):
            raise ConfigError(f"{_option(flag)} ({flag}) must be true or false, got "
                              f"{getattr(cfg, flag)!r}")
    if getattr(cfg, "start_speed", False) and (getattr(cfg, "pushforward_guards", False)
                                                 or getattr(cfg, "input_guards", False)):
        raise ConfigError("--start-speed (start_speed) does not go with --pushforward-guards "
                          "or --input-guards (their windows are led by the rest frame alone)")
    if getattr(cfg, "start_speed_noise", 0.0) > 0 and not getattr(cfg, "start_speed", False):
        raise ConfigError("--start-speed-noise (start_speed_noise) needs --start-speed (it "
                          "perturbs the start speed the step reads)")
    if getattr(cfg, "start_span", 1) != 1 and not getattr(cfg, "start_speed", False):
        raise ConfigError("--start-span (start_span) needs --start-speed (it sets the frames "
                          "the start speed is measured over)")
    if getattr(cfg, "centre_pull", 0.0) > 0 and not getattr(cfg, "follow_axis", 0.0) > 0:
        raise ConfigError("--centre-pull (centre_pull) needs --follow-axis W > 0 (it tilts the "
                          "velocities of the vessel-following prior)")
    for flag in ("wall_signed", "wall_clot_mean"):
        if getattr(cfg, flag, False) and not getattr(cfg, "wall_features", 0.0) > 0:
            raise ConfigError(f"{_option(flag)} ({flag}) needs --wall-features C > 0 (the "
                              "cutoff of the features it changes)")
    if getattr(cfg, "pushforward_guards", False) and getattr(cfg, "pushforward_steps", 0) < 1:
        raise ConfigError("--pushforward-guards (pushforward_guards) needs --pushforward-steps "
                          "P >= 1 (it guards the push-forward steps' predictions)")
    if getattr(cfg, "history_noise", 0.0) > 0 and getattr(cfg, "history", 1) < 2:
        raise ConfigError("--history-noise (history_noise) needs --history H >= 2 (it perturbs "
                          "the history's accelerations; with one previous frame there are none)")
    if getattr(cfg, "speed_noise_steady", 0.0) > 0 and not getattr(cfg, "speed_noise", 0.0) > 0:
        raise ConfigError("--speed-noise-steady (speed_noise_steady) needs --speed-noise S > 0 "
                          "(it chooses the windows that noise is drawn for)")
    if not isinstance(cfg.model_config, dict):
        raise ConfigError(f"model_config must be a JSON object, got {cfg.model_config!r}")


def check_dense_inputs(cfg, budget: int, where: str = "") -> None:
    """Refuse, before training, a sample too large for the dense wall search that signed wall
    features, wall noise, the wall term of the loss, vessel-axis features and the
    vessel-following prior use
    (:data:`thrombojax.graph.wall_nodes.DENSE_PLANE_NODES` nodes)."""
    from thrombojax.graph.wall_nodes import DENSE_PLANE_NODES

    used = [f"--{n.replace('_', '-')}" for n in ("axis_features", "follow_axis", "lateral_hold",
                                                    "outlet_features", "wall_noise",
                                                    "wall_loss_weight")
            if getattr(cfg, n, 0.0) > 0]
    if getattr(cfg, "wall_signed", False):
        used.append("--wall-signed")
    used += [f"--{n.replace('_', '-')}" for n in ("pushforward_guards", "input_guards")
             if getattr(cfg, n, False)]
    if used and budget > DENSE_PLANE_NODES:
        raise ConfigError(f"{where + ': ' if where else ''}{', '.join(used)} search the wall "
                          f"densely, for at most {DENSE_PLANE_NODES} nodes per sample; the "
                          f"samples have {budget}: subsample them (--nodes-per-sample N) or "
                          "turn those options off (e.g. --axis-features 0)")


def uses_vessel_radius(cfg) -> bool:
    """Whether a training config has an option measured in vessel radii (the training loop
    then reads the dataset's vessel radius, possibly a geometric estimate)."""
    return (cfg.noise_std > 0 or cfg.wall_features > 0 or cfg.wall_noise > 0
            or cfg.axis_features > 0 or cfg.follow_axis > 0 or cfg.lateral_hold > 0
            or cfg.outlet_features > 0 or cfg.shape_features > 0
            or cfg.clearance_features > 0 or cfg.section_features > 0
            or cfg.history_noise > 0 or cfg.select_by == "rollout"
            or cfg.pushforward_guards or cfg.input_guards)
