"""Training: data pipeline glue, the jitted step, the loop, checkpoints and trained models.

    from thrombojax.train import train, load_trained
    trained = train("bendvessel.h5", "erwin", "runs/erwin", epochs=300, bary_ratio=2.0)
    trained = load_trained("runs/erwin", which="best")   # model, params, stats, scaling, config

Modules: :mod:`~thrombojax.train.config` (the study's knobs), :mod:`~thrombojax.train.schedule`
(AdamW, warm-up + cosine), :mod:`~thrombojax.train.loss` (masked losses),
:mod:`~thrombojax.train.noise` (MeshGraphNets training noise), :mod:`~thrombojax.train.step`
(jitted train / eval steps, data parallelism, multi-host), :mod:`~thrombojax.train.state`
(state, orbax checkpoints, ``TrainedModel``), :mod:`~thrombojax.train.loop` (epochs, resume),
:mod:`~thrombojax.train.validation` (one-step validation, and the validation rollouts that pick
the checkpoint with ``select_by="rollout"``).
"""

from thrombojax.train.config import TrainConfig
from thrombojax.train.loop import TrainingDivergedError, train
from thrombojax.train.state import TrainedModel, TrainState, load_trained
from thrombojax.train.step import make_eval_step, make_train_step

__all__ = [
    "TrainConfig",
    "TrainState",
    "TrainedModel",
    "TrainingDivergedError",
    "load_trained",
    "make_eval_step",
    "make_train_step",
    "train",
]
