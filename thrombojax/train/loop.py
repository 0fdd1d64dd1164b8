"""The training loop: epochs, validation, checkpoints, exact resume, NaN guard, logs, plots.

Each optimiser step ``s`` (epoch ``e = s // steps_per_epoch``, position ``p``) is a pure function
of the run's seed and ``s``: the epoch's data order (:func:`thrombojax.data.batching.epoch_plan`),
the node subsampling (seeded by ``(seed, e, p)``) and the PRNG key
``fold_in(run_key, s)`` (augmentations, noise, dropout). The checkpoint therefore only needs the
state, the key and the step (the position is stored too, for humans and checks), and
``resume=True`` continues bit-for-bit where the last checkpoint stopped.

Per epoch: the mean training loss and MSE, the validation loss and MSE (the study's metric, the
best checkpoint is the one with the lowest validation MSE; without a validation split, the
training MSE), the learning rate and the time go to ``metrics.jsonl``; with
``select_by="rollout"`` also the validation rollout (:mod:`thrombojax.train.validation`), whose
full-length MSE then picks the best checkpoint. A non-finite loss stops
the run with :class:`TrainingDivergedError`; the last good checkpoint stays on disk.

The host reads a step's metrics one step behind (after dispatching the next step), so it
assembles the next batch while the device computes; steps that end an epoch or save a
checkpoint are read at once, so the logs, checkpoints, callbacks and resume are those of reading
every step at once (``tests/test_train_overlap.py``; speed: ``benchmarks/train_overlap.py``).
"""

from __future__ import annotations

import functools
import math
import pathlib
import time
from collections.abc import Callable
from typing import Any

import jax
import numpy as np
from tqdm.auto import tqdm

from thrombojax.data.augment import AugmentConfig, augment_batch
from thrombojax.data.batching import (
    compute_target_stats,
    epoch_plan,
    load_store,
    make_batch,
    padding_budget,
)
from thrombojax.data.radius import vessel_radius
from thrombojax.data.scaling import fit_scaling
from thrombojax.data.splits import make_split, split_simulations
from thrombojax.errors import ConfigError, OutputError, ThrombojaxError
from thrombojax.io.hdf5 import open_dataset
from thrombojax.models.registry import canonical_name, config_to_dict, create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.study import skip_frames, training_defaults
from thrombojax.train.centre_fit import centre_tolerance_of
from thrombojax.train.checks import check_dense_inputs, uses_vessel_radius
from thrombojax.train.config import RunConfig, TrainConfig, load_config_file
from thrombojax.train.guards import (
    NonFiniteError,
    check_finite,
    check_resume_dataset,
    clear_run,
    dataset_fingerprint,
    warn_schedule,
)
from thrombojax.train.memory import check_train_memory, estimate_train_memory
from thrombojax.train.plots import plot_losses
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.state import (
    TrainedModel,
    append_log,
    latest_step,
    load_trained,
    read_run_config,
    restore_checkpoint,
    save_checkpoint,
    truncate_log,
    warm_start,
    write_run_config,
)
from thrombojax.train.step import (
    data_mesh,
    init_state,
    make_eval_step,
    make_train_step,
    replicate,
    shard_batch,
)
from thrombojax.train.step_options import train_step_options
from thrombojax.train.validation import (
    end_epoch_record,
    epoch_score,
    eval_batches,
    prepare_val_rollouts,
    progress_postfix,
    val_rollout_metrics,
)

__all__ = ["train", "TrainingDivergedError", "plot_losses", "rollout_steps_at"]

_MEMORY_OPTIONS = ("bary_ratio", "batch_size", "nodes_per_sample", "bary_max_neighbors")
_OVERLAP = True  # read a step's metrics after dispatching the next (False: at once; tests)


class TrainingDivergedError(ThrombojaxError, FloatingPointError):
    """The training loss became NaN or infinite; the last good checkpoint is kept."""


def _resolve(config: Any, overrides: dict) -> tuple[TrainConfig, RunConfig | None]:
    run = None
    if config is None:
        config = TrainConfig()
    elif isinstance(config, str | pathlib.Path):
        config = load_config_file(config)
    elif isinstance(config, dict):
        config = TrainConfig.from_dict(config)
    if isinstance(config, RunConfig):
        run, config = config, config.train
    return (config.replace(**overrides) if overrides else config), run


def train(
    dataset_path: str | pathlib.Path | None,
    model_name: str | None,
    out_dir: str | pathlib.Path,
    *,
    config: TrainConfig | RunConfig | dict | str | pathlib.Path | None = None,
    resume: bool = False,
    progress: bool = True,
    callback: Callable[[int, dict], None] | None = None,
    distributed: bool = False,
    force: bool = False,
    **overrides: Any,
) -> TrainedModel:
    """Train a surrogate on a dataset and write a run directory.

    Args:
        dataset_path: a thrombojax HDF5 dataset (``None``: the dataset of a run config).
        model_name: ``mgn``, ``transolver`` or ``erwin`` (any registered model; ``None``: the
            model of a run config).
        out_dir: the run directory (created; must hold no run unless ``resume``).
        config: a :class:`TrainConfig`, its dict, a :class:`RunConfig` or a JSON file of either
            (a run's ``config.json`` repeats that run); ``overrides`` replace its fields.
        resume: continue the run in ``out_dir`` from its last checkpoint; its saved config is
            used, and overrides that contradict it raise :class:`ConfigError`.
        progress: show a tqdm progress bar.
        callback: called as ``callback(step, metrics)`` after every step (host floats), after
            any checkpoint of that step is on disk.
        distributed: call ``jax.distributed.initialize()`` first (multi-host; see
            :mod:`thrombojax.train.step`).
        force: start afresh in an ``out_dir`` that holds a run (its files are removed).
        **overrides: :class:`TrainConfig` fields.
    Returns:
        The best :class:`TrainedModel` (lowest validation MSE).
    """
    if distributed:
        jax.distributed.initialize()
    out_dir = pathlib.Path(out_dir)
    cfg, run = _resolve(config, overrides)
    dataset_path = dataset_path or (run.dataset if run else None)
    model_name = model_name or (run.model if run else None)
    if dataset_path is None or model_name is None:
        raise ConfigError("train: name a dataset and a model (or a run's config.json as config)")
    model_name = canonical_name(model_name)
    if cfg.init_from and pathlib.Path(cfg.init_from).resolve() == out_dir.resolve():
        raise OutputError(f"{out_dir}: --init-from names the run this training would write "
                          "over; give the fine-tuning a new --out")
    saved = None
    if resume:
        saved = read_run_config(out_dir)
        saved_cfg = TrainConfig.from_dict(saved["train"])
        asked = {k: v for k, v in overrides.items()
                 if k != "model_config" and getattr(saved_cfg, k) != v}
        if saved["model"] != model_name or asked:
            raise ConfigError(
                f"{out_dir}: --resume continues the saved run (model '{saved['model']}'); "
                f"conflicting options: {asked or {'model': model_name}}"
            )
        cfg = saved_cfg
        # killed before its first checkpoint: nothing to continue, start the same run afresh
        resume = latest_step(out_dir / "checkpoints" / "last") is not None
    elif latest_step(out_dir / "checkpoints" / "last") is not None:
        if not force:
            raise OutputError(f"{out_dir}: already holds a training run; use --resume, a new "
                              "--out, or --force to replace it")
        clear_run(out_dir)
    warn_schedule(cfg.epochs, cfg.warmup_epochs)
    out_dir.mkdir(parents=True, exist_ok=True)

    ds = open_dataset(dataset_path)
    ds.validate()  # the values `thrombojax info` checks, before any training
    scaling = fit_scaling(ds)
    fingerprint = dataset_fingerprint(ds)
    if saved is not None:
        check_resume_dataset(saved, fingerprint, scaling.to_dict(), dataset_path, out_dir)
    if cfg.train_sims or cfg.val_sims or cfg.test_sims:
        split = make_split(list(ds.names), test=cfg.test_sims, val=cfg.val_sims,
                           train=cfg.train_sims or None)
    else:
        split = split_simulations(list(ds.names), n_test=cfg.n_test, n_val=cfg.n_val,
                                  seed=cfg.split_seed)
    length = cfg.window_length
    train_store = load_store(ds, split.train, scaling, skip=cfg.skip_frames, length=length)
    val_store = (load_store(ds, split.val, scaling, skip=cfg.skip_frames, length=length)
                 if split.val else None)
    # isotropic with rotations, and in the vessel frame: per-axis statistics there weight the
    # loss by 1 / std^2 of an axis along which the clot barely moves (ill-conditioned)
    stats = compute_target_stats(train_store, frame=cfg.frame,
                                 isotropic=cfg.max_rotation > 0 or cfg.frame == "vessel")

    model_cfg = get_config(model_name, tiny=cfg.tiny, **cfg.model_config)
    model = create_model(model_name, model_cfg)
    study = training_defaults(model_name)
    cfg = cfg.replace(batch_size=cfg.batch_size or int(study["batch_size"]),
                      lr=cfg.lr or float(study["lr"]), model_config=config_to_dict(model_cfg))
    batch_size, lr = cfg.batch_size, cfg.lr
    mesh = data_mesh()
    if batch_size % mesh.size:
        raise ConfigError(f"batch size {batch_size} is not a multiple of the {mesh.size} devices")
    max_nodes = max(train_store.max_nodes, val_store.max_nodes if val_store else 0)
    budget = padding_budget(max_nodes, cfg.nodes_per_sample)
    check_dense_inputs(cfg, budget, where=str(dataset_path))
    # training windows led by the rest frame
    lead = cfg.rest_edges or cfg.pushforward_guards or cfg.input_guards
    start_speed = ((skip_frames(ds), cfg.history, cfg.start_span) if cfg.start_speed
                   else None)  # 2 lead frames
    check_train_memory(estimate_train_memory(
        n_windows=len(train_store), n_val_windows=len(val_store) if val_store else 0,
        bary_ratio=cfg.bary_ratio, batch_size=batch_size, budget=budget,
        length=length + lead + 2 * bool(start_speed), max_neighbors=cfg.bary_max_neighbors,
    ), values={k: getattr(cfg, k) for k in _MEMORY_OPTIONS}, where=str(dataset_path))
    plan_of = functools.partial(epoch_plan, len(train_store), bary_ratio=cfg.bary_ratio,
                                batch_size=batch_size, seed=cfg.seed)
    steps_per_epoch = plan_of(epoch=0).shape[0]
    total_steps = cfg.epochs * steps_per_epoch
    schedule = make_schedule(lr, total_steps, round(cfg.warmup_epochs * steps_per_epoch))
    tx = make_optimizer(schedule, weight_decay=cfg.weight_decay, grad_clip=cfg.grad_clip)
    batch_of = functools.partial(make_batch, train_store, budget=budget, seed=cfg.seed,
                                 nodes_per_sample=cfg.nodes_per_sample, rest=lead,
                                 start_speed=start_speed)
    run_key, init_key = jax.random.split(jax.random.PRNGKey(cfg.seed))
    # radii -> scaled; the radius (possibly a geometric estimate) only when it is needed
    radius = vessel_radius(ds) / float(scaling.scale) if uses_vessel_radius(cfg) else 0.0
    wall_cutoff = cfg.wall_features * radius
    centre_tolerance, centre_fit = centre_tolerance_of(cfg, ds, split.train)
    step_fn = make_step(model, cfg.frame, wall_cutoff, history=cfg.history,
                        stop_history_gradient=cfg.stop_history_gradient,
                        wall_signed=cfg.wall_signed, axis_radius=cfg.axis_features * radius,
                        prior_radius=cfg.follow_axis * radius,
                        lateral_radius=cfg.lateral_hold * radius,
                        wall_clot_mean=cfg.wall_clot_mean,
                        outlet_radius=cfg.outlet_features * radius,
                        shape_radius=cfg.shape_features * radius, rest_edges=cfg.rest_edges,
                        start_speed=cfg.start_span * cfg.start_speed,
                        clearance_radius=cfg.clearance_features * radius,
                        section_radius=cfg.section_features * radius,
                        centre_pull=cfg.centre_pull, centre_unit=radius * (cfg.centre_pull > 0),
                        centre_tolerance=centre_tolerance * radius)
    state = init_state(step_fn, tx, init_key, batch_of(plan_of(epoch=0)[0]),
                       average=cfg.average_weights > 0)
    if cfg.init_from and not resume:  # the weights of another run (fine-tuning)
        state = warm_start(state, tx, cfg.init_from, cfg.init_which, model_name)
    run_config = {
        **RunConfig(model=model_name, dataset=str(pathlib.Path(dataset_path).resolve()),
                    train=cfg).to_dict(),
        "stats": stats.to_dict(), "scaling": scaling.to_dict(), "budget": budget,
        "dataset_fingerprint": fingerprint, "wall_cutoff": wall_cutoff,
        "axis_radius": step_fn.axis_radius, "prior_radius": step_fn.prior_radius,
        "lateral_radius": step_fn.lateral_radius, "outlet_radius": step_fn.outlet_radius,
        "shape_radius": step_fn.shape_radius, "units": str(ds.attrs.get("units", "")),
        "clearance_radius": step_fn.clearance_radius,
        "section_radius": step_fn.section_radius, "centre_unit": step_fn.centre_unit,
        "centre_tolerance": step_fn.centre_tolerance, "centre_tolerance_fit": centre_fit,
        "steps_per_epoch": steps_per_epoch, "total_steps": total_steps, "devices": mesh.size,
        "split": split.to_dict(),
    }
    best = math.inf
    acc = np.zeros(3)  # running (loss * nodes, mse * nodes, nodes) of the current epoch
    if resume:
        state, run_key, meta = restore_checkpoint(out_dir / "checkpoints" / "last", state, run_key)
        best, acc = float(meta["best"]), np.asarray(meta["epoch_acc"], np.float64)
        truncate_log(out_dir / "metrics.jsonl", int(state.step))
    elif jax.process_index() == 0:
        write_run_config(out_dir, run_config)
        (out_dir / "metrics.jsonl").write_text("")

    aug_cfg = AugmentConfig(
        max_rotation=cfg.max_rotation, uniform_rotation=cfg.uniform_rotation,
        barycentric=cfg.bary_ratio > 0,
        radius=cfg.bary_radius or model_cfg.radius, max_neighbors=cfg.bary_max_neighbors,
    )
    augment = jax.jit(functools.partial(augment_batch, config=aug_cfg))
    train_steps: dict[int, Callable] = {}
    step_options = train_step_options(cfg, radius, total_steps)

    def train_step_at(epoch: int) -> Callable:
        k = rollout_steps_at(epoch, cfg.rollout_steps, cfg.curriculum_epochs)
        if k not in train_steps:  # one compilation per k of the curriculum
            train_steps[k] = make_train_step(step_fn, tx, stats, k=k, **step_options)
        return train_steps[k]

    eval_step = make_eval_step(step_fn, stats, k=cfg.rollout_steps)
    val_batches = eval_batches(val_store, budget, batch_size, cfg, start_speed) if val_store else []
    val_rollouts = (functools.partial(val_rollout_metrics, stats=stats, radius=radius, sims=(
        prepare_val_rollouts(ds, split.val, scaling, step_fn, n_nodes=cfg.nodes_per_sample,
                             seed=cfg.seed))) if cfg.select_by == "rollout" else None)
    state = replicate(state, mesh)
    ckpt = out_dir / "checkpoints"

    def checkpoint(which: str, epoch: int, position: int) -> None:
        meta = {"epoch": epoch, "position": position, "best": best, "epoch_acc": acc.tolist(),
                **run_config}
        save_checkpoint(ckpt / which, jax.device_get(state), run_key, meta)

    start = int(jax.device_get(state.step))
    bar = tqdm(total=total_steps, initial=start, disable=not progress, desc=f"train {model_name}")
    t0 = time.perf_counter()

    def settle(step: int, epoch: int, device_metrics: dict) -> dict:
        """A dispatched step's metrics on the host (waits for it); a non-finite loss stops."""
        nonlocal acc
        metrics = {k: float(v) for k, v in jax.device_get(device_metrics).items()}
        if not math.isfinite(metrics["loss"]):
            append_log(out_dir, {"event": "nan", "step": step + 1, "epoch": epoch, **metrics})
            raise TrainingDivergedError(
                f"{out_dir}: training loss became {metrics['loss']} at step {step + 1} "
                f"(epoch {epoch}); the last good checkpoint is kept in {ckpt / 'last'}; "
                "lower --lr or set grad_clip"
            )
        acc += np.array([metrics["loss"], metrics["mse"], 1.0]) * metrics["nodes"]
        return metrics

    def done(step: int, metrics: dict) -> None:
        bar.update(1)
        if callback is not None:
            callback(step + 1, metrics)

    # one step behind: a step's metrics are read after the next step is dispatched, so the host
    # assembles the next batch while the device computes. A step that ends an epoch or saves a
    # checkpoint is read at once (before its state is saved, evaluated or donated to the next
    # step), so no checkpoint follows an unchecked loss and every epoch ends with none pending.
    pending = None  # (step, epoch, metrics on the device) of the step not read yet
    for epoch in range(start // steps_per_epoch, cfg.epochs):
        plan = plan_of(epoch=epoch)
        for position in range(start - epoch * steps_per_epoch if epoch == start // steps_per_epoch
                              else 0, steps_per_epoch):
            step = epoch * steps_per_epoch + position
            aug_key, step_key = jax.random.split(jax.random.fold_in(run_key, step))
            host_batch = batch_of(plan[position], epoch=epoch, position=position)
            batch = augment(aug_key, shard_batch(host_batch, mesh))
            state, device_metrics = train_step_at(epoch)(state, batch, step_key)
            if pending is not None:
                done(pending[0], settle(*pending))
                pending = None
            last_of_epoch = position == steps_per_epoch - 1
            save = cfg.checkpoint_every and (step + 1) % cfg.checkpoint_every == 0
            if _OVERLAP and not (last_of_epoch or save):
                pending = (step, epoch, device_metrics)
                continue
            metrics = settle(step, epoch, device_metrics)
            if last_of_epoch:
                record = end_epoch_record(epoch, step + 1, acc, val_batches, eval_step, state, mesh,
                                    float(schedule(step)), time.perf_counter() - t0)
                try:  # never save a checkpoint whose metrics are NaN / infinite
                    check_finite(record, f"{out_dir}: epoch {epoch + 1}")
                except NonFiniteError as err:
                    append_log(out_dir, record)
                    raise TrainingDivergedError(f"{err}; not saved, the last good checkpoint is "
                                                f"kept in {ckpt / 'last'}") from err
                if val_rollouts is not None:  # a diverged rollout is a result (None), not NaN
                    record |= val_rollouts(state.model_params)
                append_log(out_dir, record)
                score = epoch_score(record, cfg.select_by)
                acc = np.zeros(3)
                if score < best or math.isinf(best):  # no finite rollout yet: the latest
                    best = score
                    checkpoint("best", epoch + 1, 0)
                checkpoint("last", epoch + 1, 0)
                bar.set_postfix(progress_postfix(record))
            elif save:
                checkpoint("last", epoch, position + 1)
            done(step, metrics)
    bar.close()
    if jax.process_index() == 0:
        plot_losses(out_dir / "metrics.jsonl", out_dir / "loss.png", cfg.select_by)
    return load_trained(out_dir, which="best")


def rollout_steps_at(epoch: int, k: int, curriculum_epochs: float) -> int:
    """k of the unrolled loss in ``epoch``: grows linearly from 1 to ``k`` over
    ``curriculum_epochs`` epochs (``1 + floor(epoch * k / curriculum_epochs)``), else ``k``."""
    if curriculum_epochs <= 0:
        return k
    return int(max(1, min(k, 1 + math.floor(epoch * k / curriculum_epochs))))

