"""Named training recipes: sets of :class:`~thrombojax.train.config.TrainConfig` fields.

* ``"outlet"`` (the default of ``thrombojax train`` and ``make demo``): ``room`` plus the
  outlet features (``outlet_features=2.0``: every clot node reads where the clot stands against
  the vessel's open end, per node and clot-wide,
  :func:`thrombojax.graph.vessel_axis.outlet_features`), so the step speeds the clot up as it
  leaves the vessel, where ``room``'s step holds it back. The stability ladder's
  ``follow_room30_outlet_last`` rung. Measured against ``room`` on the same seeds (guarded at
  the fitted coherence tolerance):

  - BendVessel's held-out simulations (seeds 0 and 1, 37 epochs): 0.76 / 0.94 r off at the end
    (``room``: 2.24 / 1.62 r), the two as one ensemble 0.69 r (1.93 r); the exit costs 0.63 /
    0.90 r instead of 1.89 / 1.64 r; one step 2.5-2.8x CV in the rollout phase (6.0x); alone
    24-26 % of the clot outside at worst (26-31 %)
    (``experiments/results/ladder_budget/bendvessel_speed_noise/``);
  - ClotEntry's held-out pair (2-epoch seeds 13-16): 0.84-3.98 r, mean 2.06 r (``room``:
    0.85-4.73 r, mean 2.71 r), the four as one ensemble 1.63 r (1.31 r), none outside: two
    seeds nearer, two farther, within the seed-to-seed spread
    (``experiments/results/ladder_budget/clotentry_outlet/``);
  - ``make demo``, the same day and data: 0.02x CV over the rollout and 1.11 r at the end
    (``room``: 0.08x, 2.40 r) (``experiments/results/demo/``).

  An epoch costs about 9 % more than ``room``'s (the outlet features search the vessel nodes
  around every clot node). Its features need a dense search: at most 8,192 nodes per sample.
* ``"room"`` (the default before ``outlet``): ``axis`` without the
  history frame (``history=1``) plus what made ClotEntry's rollouts follow the vessel: the
  vessel-following prior (``follow_axis=2.0``: the step moves the clot along the vessel axis at
  its speed and the model learns the rest), wall features cut off at 0.5 vessel radii with the
  clot-wide mean of the clipped wall distance as one more input (``wall_clot_mean``: the
  clot's room in the vessel, which sets its speed), the clot-wide error weighted 10x
  (``clot_mean_weight``), speed noise 0.3 (the clot's input motion scaled by
  ``1 + N(0, 0.3^2)``, the target unchanged) and the last epoch's checkpoint. The stability
  ladder's ``follow_room30_last`` rung. Measured against ``axis`` (guarded unless said;
  r = vessel radii, CV = constant velocity):

  - ClotEntry: single 6-epoch seeds end 0.92-4.76 r off the held-out clots (``axis``, 4
    epochs: 3.1 and 14.2 r), and five 2-epoch seeds as one ensemble 0.55-2.16 r over seven
    draws, 1.41 r on average, none outside
    (``experiments/results/ladder_budget/clotentry_speed_room/``, ``.../clotentry_five/``);
  - ``make demo``, the same day and budget: 0.21x CV over the rollout, 3.04 r, where ``axis``
    is worse than CV (1.08x, 3.43 r) (``experiments/results/demo/``);
  - BendVessel's held-out simulations (seed 0, 28 minutes): closer on the way (0.12x CV
    against 0.18x on the same data) but further at the end (2.60 r against 1.90 r), and alone
    nearer (1.41 r against 1.91 r, 26 % of the clot outside at worst against 54 %)
    (``experiments/results/ladder_budget/bendvessel_room/``).

  Its one step is worse than CV (6.0x in BendVessel's rollout phase; ``axis`` 0.35x): the
  step keeps a fifth of the speed it is shown and takes the rest from the vessel. On
  BendVessel it follows the slide (within 0.36 r along the track when the exit begins) and
  loses 1.6-1.9 r as the true clot speeds up out of the vessel; with speed noise 0.1 the step
  keeps its speed (1.2x CV) but the clot speeds up over the slide and runs ahead
  (``experiments/results/ladder_budget/bendvessel_speed_noise/``). Its features need a
  dense search: at most 8,192 nodes per sample (``--nodes-per-sample``).
* ``"axis"`` (the default before ``room``): ``history`` plus the
  clot's velocity split along and across the local vessel axis (``axis_features=2.0``: the
  axis from the wall normals within about 2 vessel radii,
  :mod:`thrombojax.graph.vessel_axis`). The stability ladder's ``walk_axis`` rung: at the
  same training it rolled out better than ``history`` on both datasets, guarded, on BendVessel
  (0.11x constant velocity against 0.19x, the clot 0.87 r off against 2.31 r; alone 0.22x) and
  on ClotEntry (0.03x against 0.20x, 3.1 r against 14.0 r; a second seed there 0.20x, 14.2 r)
  (``experiments/results/ladder_budget/bendvessel_axis/``, ``.../clotentry_axis/``); in the
  demo's small split it did worse than ``history`` (``experiments/results/demo/``). Its
  features need a dense search: at most 8,192 nodes per sample (``--nodes-per-sample``).
* ``"history"`` (the default before ``axis``): the stability ladder's ``history_walk`` rung
  (``experiments/ladder.py``): the step also reads the acceleration before t
  (``history=2``), trained with the single-step loss under input noise (0.01 vessel radii)
  that is a random walk over both input velocities, random rotations up to pi, plus the
  guards that ``thrombojax rollout`` applies by default. An epoch costs about a quarter of
  the ``rollout`` recipe's; at the same CPU time (5x the epochs) every seed rolled
  out better than that recipe (``experiments/results/ladder_budget/``).
* ``"rollout"``: the ladder's ``rotation`` rung, the default until the history recipe was
  measured at equal CPU time: input noise (0.01 vessel radii), one push-forward step, a 3-step
  unrolled loss grown by a curriculum over 6 epochs, random rotations up to pi. (The rigid
  vessel's frame, ``frame="vessel"``, is invariant to orientation and gave the best
  single-step error, but its k-step training diverged in the ladder, with and without gradient
  clipping; it stays an option. With ``axis`` and ``--swell-noise 0.1`` it gives BendVessel's
  best models, but does worse than the global frame on a vessel no model saw:
  ``experiments/results/ladder_budget/bendvessel_frame/``.)
* ``"robust"``: ``history`` plus what keeps the model alone (no guards) on its path: wall
  noise (clot nodes near the wall pushed through it, the target bringing them back, 0.1
  vessel radii) with signed wall features (the signed distance to the wall and its normal,
  cut off at 0.5 r), history noise (0.02 r: the history's clot-wide acceleration not carried
  over), speed and direction noise (the clot's input motion scaled by ``1 + N(0, 0.1^2)`` and
  turned by ``N(0, 0.1^2)`` rad, the target unchanged), and the last epoch's checkpoint
  (``select_by="last"``: with this much noise the one-step validation MSE hardly moves and
  picked undertrained epochs). The stability ladder's ``robust`` rung (its ``dirspeed_last``
  rungs evaluate the same recipe): on BendVessel all five seeds roll out at 0.29-0.39x
  constant velocity alone (``experiments/results/ladder_budget/bendvessel_last/``), but on
  ClotEntry it fell to 0.61x where ``history`` gives 0.13x
  (``experiments/results/ladder_budget/clotentry_robust/``).
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

_HISTORY = {
    "noise_std": 0.01,
    "max_rotation": math.pi,
    "history": 2,
    "noise_walk": True,
}
_AXIS = {**_HISTORY, "axis_features": 2.0}
_ROOM = {  # `axis` without the history frame, plus:
    **_AXIS,
    "history": 1,
    "follow_axis": 2.0,
    "wall_features": 0.5,
    "wall_clot_mean": True,
    "clot_mean_weight": 10.0,
    "speed_noise": 0.3,
    "select_by": "last",
}

RECIPES: types.MappingProxyType = types.MappingProxyType({
    "rollout": types.MappingProxyType({
        "noise_std": 0.01,
        "pushforward_steps": 1,
        "rollout_steps": 3,
        "curriculum_epochs": 6.0,
        "max_rotation": math.pi,
    }),
    "axis": types.MappingProxyType(dict(_AXIS)),
    "history": types.MappingProxyType(dict(_HISTORY)),
    "robust": types.MappingProxyType({
        **_HISTORY,
        "wall_noise": 0.1,
        "wall_features": 0.5,
        "wall_signed": True,
        "history_noise": 0.02,
        "speed_noise": 0.1,
        "direction_noise": 0.1,
        "select_by": "last",
    }),
    "room": types.MappingProxyType(dict(_ROOM)),
    "outlet": types.MappingProxyType({**_ROOM, "outlet_features": 2.0}),
    "study": types.MappingProxyType({}),
})
"""Recipe name -> the TrainConfig fields it sets (read-only)."""

DEFAULT_RECIPE: str = "outlet"


def recipe(name: str) -> dict:
    """The TrainConfig fields of recipe ``name`` (a fresh dict); unknown names raise
    :class:`ConfigError` naming the known ones."""
    try:
        return dict(RECIPES[name])
    except KeyError:
        raise ConfigError(f"--recipe: unknown recipe {name!r}; known: {', '.join(RECIPES)}") \
            from None
