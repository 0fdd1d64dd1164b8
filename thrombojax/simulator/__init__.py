"""The learned simulator: one learned step (:mod:`.step`) and its rollouts (:mod:`.rollout`).

This layer sits between the models and everything that runs them: training losses, evaluation
and benchmarks call :func:`thrombojax.simulator.step.make_step` and never rebuild the step.
Rollout guards that act on the step's output belong here too.
"""
