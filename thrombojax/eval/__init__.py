"""The evaluation layer: everything that measures a trained surrogate or shows it.

Modules: :mod:`~thrombojax.eval.metrics` (errors, centroid, containment),
:mod:`~thrombojax.eval.single_step` (the study's single-step metric, ``thrombojax evaluate``),
:mod:`~thrombojax.eval.phases` (single-step errors by phase: start, rollout, exit),
:mod:`~thrombojax.eval.physical` (errors in vessel radii, the conversion recorded),
:mod:`~thrombojax.eval.truth_tables` (the markdown of ``evaluate.md`` and ``rollout.md``),
:mod:`~thrombojax.eval.rollouts` (a rollout measured beside the truth and constant velocity),
:mod:`~thrombojax.eval.drift` (a rollout's speed-up: the clot's speed per step, a step's
history gain),
:mod:`~thrombojax.eval.track` (a rollout's centroid error along and across the true track, its
clot's size against the truth's),
:mod:`~thrombojax.eval.pace_fit` (a factor on the learned steps fitted on validation
simulations so that the clot ends on the true one along its track),
:mod:`~thrombojax.eval.report` (``thrombojax rollout``: trajectories, ParaView files, plots),
:mod:`~thrombojax.eval.rollout_pull` (the prior's centring pull set at rollout time,
``thrombojax rollout --centre-pull``),
:mod:`~thrombojax.eval.plots` (matplotlib figures and animations),
:mod:`~thrombojax.eval.bench` (rollout speed, ``thrombojax bench``) and
:mod:`~thrombojax.eval.tables` (markdown tables, the environment record).
Nothing below this layer (``train/``, ``simulator/``, ``models/``, ...) imports it.
"""
