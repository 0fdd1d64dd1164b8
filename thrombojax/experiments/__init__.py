"""The study's experiments from one command (``thrombojax experiment``).

- :mod:`.spec`: experiment files (``experiments/configs/*.toml``), three scales each, ``--set``.
- :mod:`.plan`: the run list, ``--worker i/n`` sharding, the cost estimate.
- :mod:`.data`: datasets generated on demand and cached.
- :mod:`.execute`: one run (train or resume, measure, ``result.json``).
- :mod:`.tensorboard`: TensorBoard event files beside ``metrics.jsonl``.
- :mod:`.report`: seeds aggregated, the study's numbers beside ours, the plots.
- :mod:`.runner`: a whole experiment, resumable. :mod:`.search`: the Optuna search.
"""

from thrombojax.experiments.plan import Run, estimate, parse_worker, plan_runs, shard
from thrombojax.experiments.runner import run_experiment
from thrombojax.experiments.spec import (
    Experiment,
    Scale,
    apply_sets,
    find_experiment,
    list_experiments,
    load_experiment,
)

__all__ = [
    "Experiment",
    "Scale",
    "Run",
    "load_experiment",
    "find_experiment",
    "list_experiments",
    "apply_sets",
    "plan_runs",
    "shard",
    "parse_worker",
    "estimate",
    "run_experiment",
]
