"""Named training recipes: sets of :class:`~thrombojax.train.config.TrainConfig` fields.

* ``"rollout"`` (the default of ``thrombojax train`` and ``make demo``): the best rung of the
  stability ladder (``experiments/ladder.py``, results in ``experiments/results/ladder/``):
  input noise, one push-forward step, a 3-step unrolled loss grown by a curriculum, the step in
  the rigid vessel's frame (orientation-invariant, so no rotation augmentation), plus the
  guards that ``thrombojax rollout`` applies by default.
* ``"study"``: the study's single-step recipe, i.e. :class:`TrainConfig`'s own defaults (random
  rotations up to pi, no noise, one-step loss): for reproducing the study's tables.

Precedence in ``thrombojax train``: TrainConfig defaults < ``--config`` file < recipe <
command-line options. With ``--config`` or ``--resume`` a recipe applies only when
``--recipe`` is given (a config file, a run's ``config.json`` above all, describes its run
completely; a resumed run continues with its saved options).
"""

from __future__ import annotations

import types

from thrombojax.errors import ConfigError

__all__ = ["RECIPES", "DEFAULT_RECIPE", "recipe"]

RECIPES: types.MappingProxyType = types.MappingProxyType({
    "rollout": types.MappingProxyType({
        "noise_std": 0.01,
        "pushforward_steps": 1,
        "rollout_steps": 3,
        "curriculum_epochs": 6.0,
        "frame": "vessel",
        "max_rotation": 0.0,
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
