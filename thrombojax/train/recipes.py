"""Named training recipes: sets of :class:`~thrombojax.train.config.TrainConfig` fields.

* ``"rollout"`` (the default of ``thrombojax train`` and ``make demo``): the best rung of the
  stability ladder (``experiments/ladder.py``, results in ``experiments/results/ladder/``):
  input noise (0.01 vessel radii), one push-forward step, a 3-step unrolled loss grown by a
  curriculum over 6 epochs, random rotations up to pi, plus the guards that ``thrombojax
  rollout`` applies by default. (The rigid vessel's frame, ``frame="vessel"``, is exactly
  invariant to orientation and gave the best single-step error, but its k-step training
  diverged in the ladder, with and without gradient clipping; it stays an option.)
* ``"study"``: the study's single-step recipe, i.e. :class:`TrainConfig`'s own defaults (random
  rotations up to pi, no noise, one-step loss): for reproducing the study's tables.

Precedence in ``thrombojax train``: TrainConfig defaults < ``--config`` file < recipe <
command-line options. With ``--config`` or ``--resume`` a recipe applies only when
``--recipe`` is given (a config file, a run's ``config.json`` above all, describes its run
completely; a resumed run continues with its saved options).
"""

from __future__ import annotations

import math
import types

from thrombojax.errors import ConfigError

__all__ = ["RECIPES", "DEFAULT_RECIPE", "recipe"]

RECIPES: types.MappingProxyType = types.MappingProxyType({
    "rollout": types.MappingProxyType({
        "noise_std": 0.01,
        "pushforward_steps": 1,
        "rollout_steps": 3,
        "curriculum_epochs": 6.0,
        "max_rotation": math.pi,
    }),
    "study": types.MappingProxyType({}),
})
"""Recipe name -> the TrainConfig fields it sets (read-only)."""

DEFAULT_RECIPE: str = "rollout"


def recipe(name: str) -> dict:
    """The TrainConfig fields of recipe ``name`` (a fresh dict); unknown names raise
    :class:`ConfigError` naming the known ones."""
    try:
        return dict(RECIPES[name])
    except KeyError:
        raise ConfigError(f"--recipe: unknown recipe {name!r}; known: {', '.join(RECIPES)}") \
            from None
