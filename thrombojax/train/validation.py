"""Validation during training: the one-step validation batches and, optionally, rollouts
that pick the checkpoint by how its rollout holds.

:func:`eval_batches` and :func:`end_epoch_record`: every validation window once per epoch, in
order, with a fixed node subset; the epoch's record of ``metrics.jsonl``.

The one-step validation MSE says little about a rollout: with noisy training recipes it hardly
moves from epoch to epoch while the rollout changes several-fold, so its lowest epoch can be an
undertrained one (epoch 5 of 25 of a run whose last epoch rolls out at 0.36x the
constant-velocity (CV) baseline and epoch 5 at 1.80x;
``experiments/results/ladder_budget/bendvessel_select/README.md``). With ``select_by="rollout"``
(``thrombojax train --select-by rollout``) every epoch ends with a rollout of the model alone
(no guards) on each validation simulation, from the dataset's skipped frames
(:func:`thrombojax.study.skip_frames`, at least 1) to its last frame, the same rollout
``thrombojax evaluate`` and the stability ladder measure; the ``best`` checkpoint is then the one
with the lowest mean full-length rollout MSE.

:func:`prepare_val_rollouts` reads the simulations once (their start frames, truth, CV
baseline); :func:`val_rollout_metrics` rolls the current parameters out (one
compilation per simulation shape: the parameters are an argument of the compiled rollout) and
returns, per epoch, in scaled units and in vessel radii:

- ``val_rollout_mse``: mean over simulations of the full-length rollout MSE (scaled; the
  selection score) and ``val_rollout_mse_r2`` (vessel radii squared);
- ``val_rollout_cv_ratio``: the summed rollout MSE over the summed CV rollout MSE (< 1 beats CV);
- ``val_rollout_centroid_r``: mean final clot-centroid error, vessel radii.

The errors are those of :mod:`thrombojax.eval.metrics` (``mse_per_step``, ``centroid_error``),
written here again because training sits below evaluation in the package's layers
(``tests/test_val_rollout.py`` checks they agree). The share of the clot outside the vessel is
left to ``thrombojax evaluate``.

Training does not depend on it: the rollouts use no random key, so a run's parameters at every
step are those of the same run without validation rollouts (``tests/test_val_rollout.py``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import jax
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.batching import epoch_plan, make_batch
from thrombojax.errors import ConfigError
from thrombojax.simulator.grid_step import allocate_grid
from thrombojax.simulator.rollout import constant_velocity_rollout, rollout
from thrombojax.simulator.step import LearnedStep
from thrombojax.train.step import shard_batch
from thrombojax.types import TargetStats, clot_mask

__all__ = ["VAL_ROLLOUT_KEYS", "ValSimulation", "prepare_val_rollouts", "val_rollout_metrics",
           "epoch_score", "progress_postfix", "eval_batches", "end_epoch_record"]

_EVAL_EPOCH = 2**31 - 1  # seed stream of the validation subsets, never a training epoch

VAL_ROLLOUT_KEYS = ("val_rollout_mse", "val_rollout_mse_r2", "val_rollout_cv_ratio",
                    "val_rollout_centroid_r")
"""The keys :func:`val_rollout_metrics` adds to each epoch's record in ``metrics.jsonl``."""


@dataclasses.dataclass(frozen=True)
class ValSimulation:
    """One validation simulation ready to roll out (host arrays, scaled coordinates).

    Attributes:
        name: simulation name. step: the learned step for it (a cell grid where it pays).
        x_prev, x0: the step's history before the start frame and the start frame.
        node_type: ``[n]``. true: ``[n_steps, n, 3]`` the frames after the start.
        cv_mse: the constant-velocity rollout's full-length MSE (scaled).
        clot: ``[n]`` bool clot nodes.
    """

    name: str
    step: LearnedStep
    x_prev: np.ndarray
    x0: np.ndarray
    node_type: np.ndarray
    true: np.ndarray
    cv_mse: float
    clot: np.ndarray


def prepare_val_rollouts(
    dataset, names: Sequence[str], scaling, step: LearnedStep, *,
    n_nodes: int | None = None, seed: int = 0,
) -> list[ValSimulation]:
    """Read each validation simulation once: start frames, truth, CV baseline.

    Args:
        dataset: the open training dataset. names: its validation simulations (at least one).
        scaling: the run's :class:`~thrombojax.data.scaling.Scaling`.
        step: the run's learned step.
        n_nodes: roll out a fixed seeded node subset of this size (the run's
            ``nodes_per_sample``), or every node.
        seed: the subset's seed.
    Returns:
        One :class:`ValSimulation` per name.
    """
    if not names:
        raise ConfigError("select_by 'rollout' needs validation simulations (--n-val >= 1 or "
                          "--val-sims)")
    t0 = max(study.skip_frames(dataset), 1)
    sims = []
    for name in names:
        full = np.asarray(scaling.apply(np.asarray(dataset.positions(name), np.float32)),
                          np.float32)
        full_nt = np.asarray(dataset.node_type(name), np.int32)
        if full.shape[0] < t0 + 2:
            raise ConfigError(f"{dataset.path}: simulation '{name}' has {full.shape[0]} frames; "
                              f"a validation rollout from frame {t0} needs at least {t0 + 2}")
        idx = subsample_indices(seed, full_nt, n_nodes or len(full_nt))
        pos, nt = full[:, idx], full_nt[idx]
        n = pos.shape[0] - 1 - t0
        mask = np.ones(len(nt), bool)
        clot = clot_mask(nt)
        true = pos[t0 + 1:]
        cv = constant_velocity_rollout(pos[t0 - 1], pos[t0], nt, mask, n)
        sims.append(ValSimulation(
            name=name, step=allocate_grid(step, pos[t0 - 1:], nt),
            x_prev=np.asarray(step.previous(pos, t0)), x0=pos[t0], node_type=nt, true=true,
            cv_mse=float(_mse_per_step(cv, true, clot).mean()), clot=clot))
    return sims


def val_rollout_metrics(params, stats: TargetStats, sims: Sequence[ValSimulation],
                        radius: float) -> dict[str, float]:
    """Roll ``params`` out (model alone) on every validation simulation and measure it.

    Args:
        params, stats: the model's current parameters and target statistics.
        sims: from :func:`prepare_val_rollouts`.
        radius: one vessel radius in scaled coordinates (the ``_r`` values).
    Returns:
        ``val_rollout_mse``, ``val_rollout_mse_r2``, ``val_rollout_cv_ratio``,
        ``val_rollout_centroid_r`` (see the module docstring); all
        ``None`` when a rollout went non-finite (``null`` in ``metrics.jsonl``; never the best).
    """
    mse, cv, centroid = [], [], []
    for sim in sims:
        n = sim.true.shape[0]
        mask = np.ones(len(sim.node_type), bool)
        pred = np.asarray(rollout(sim.step, params, stats, sim.x_prev, sim.x0, sim.node_type,
                                  mask, n))
        if not np.isfinite(pred).all():  # the rollout blew up: no value is meaningful
            return dict.fromkeys(VAL_ROLLOUT_KEYS)
        mse.append(float(_mse_per_step(pred, sim.true, sim.clot).mean()))
        cv.append(sim.cv_mse)
        centroid.append(float(_final_centroid_error(pred, sim.true, sim.clot)))
    mean_mse = float(np.mean(mse))
    return {
        "val_rollout_mse": mean_mse,
        "val_rollout_mse_r2": mean_mse / radius**2,
        "val_rollout_cv_ratio": float(np.sum(mse) / max(np.sum(cv), 1e-30)),
        "val_rollout_centroid_r": float(np.mean(centroid)) / radius,
    }


def _mse_per_step(pred: np.ndarray, true: np.ndarray, clot: np.ndarray) -> np.ndarray:
    """``[n_steps]`` squared error over clot nodes and axes (``eval.metrics.mse_per_step``)."""
    diff = np.asarray(pred, np.float64)[:, clot] - np.asarray(true, np.float64)[:, clot]
    return (diff**2).mean(axis=(1, 2))


def _final_centroid_error(pred: np.ndarray, true: np.ndarray, clot: np.ndarray) -> float:
    """Distance of the last frame's clot centroids (``eval.metrics.centroid_error``)."""
    c = [np.asarray(x[-1], np.float64)[clot].mean(axis=0) for x in (pred, true)]
    return float(np.linalg.norm(c[0] - c[1]))


def epoch_score(record: dict, select_by: str) -> float:
    """What the ``best`` checkpoint minimises in an epoch's record: ``val_rollout_mse``
    (``select_by="rollout"``; infinite when the rollout diverged), minus the epoch
    (``"last"``: every epoch beats the one before) or ``val_mse``; the training MSE without a
    validation split."""
    if select_by == "last":
        return -float(record["epoch"])
    key = "val_rollout_mse" if select_by == "rollout" else "val_mse"
    score = record.get(key, record["train_mse"])
    return math.inf if score is None else float(score)


def progress_postfix(record: dict) -> dict[str, str]:
    """The progress bar's loss, validation MSE and, when measured, the rollout's ratio to CV."""
    out = {"loss": f"{record['train_loss']:.3g}",
           "val": f"{record.get('val_mse', float('nan')):.3g}"}
    if "val_rollout_cv_ratio" in record:
        ratio = record["val_rollout_cv_ratio"]
        out["rollout/CV"] = "diverged" if ratio is None else f"{ratio:.3g}"
    return out


def eval_batches(store, budget: int, batch_size: int, cfg,
                 start_speed: tuple[int, int] | None = None) -> list:
    """Validation batches: every window once, in order, no augmentation, with a fixed node subset
    (seeded by ``(seed, _EVAL_EPOCH, batch)``, the same every epoch); ``start_speed``: as
    :func:`~thrombojax.data.batching.make_batch`'s."""
    plan = epoch_plan(len(store), bary_ratio=0.0, batch_size=batch_size, seed=cfg.seed, epoch=0)
    plan = plan.reshape(-1, 2)
    order = np.argsort(np.where(plan[:, 0] < 0, len(store), plan[:, 0]), kind="stable")
    plan = plan[order].reshape(-1, batch_size, 2)
    return [
        make_batch(store, entries, budget, nodes_per_sample=cfg.nodes_per_sample,
                   seed=cfg.seed, epoch=_EVAL_EPOCH, position=i, rest=cfg.rest_edges,
                   start_speed=start_speed)
        for i, entries in enumerate(plan)
    ]


def end_epoch_record(epoch, step, acc, val_batches, eval_step, state, mesh, lr,
                     elapsed) -> dict:
    """An epoch's record: mean training loss and MSE (``acc``: sums weighted by nodes), the
    one-step validation loss and MSE over ``val_batches``, the learning rate and the time."""
    nodes = max(acc[2], 1.0)
    record = {"epoch": epoch + 1, "step": step, "train_loss": acc[0] / nodes,
              "train_mse": acc[1] / nodes, "lr": lr, "time_s": elapsed}
    if val_batches:
        tot = np.zeros(3)
        for batch in val_batches:
            m = jax.device_get(eval_step(state.model_params, shard_batch(batch, mesh)))
            tot += np.array([m["loss"], m["mse"], 1.0]) * float(m["nodes"])
        record["val_loss"] = tot[0] / max(tot[2], 1.0)
        record["val_mse"] = tot[1] / max(tot[2], 1.0)
    return {k: float(v) if isinstance(v, np.floating | float) else v for k, v in record.items()}
