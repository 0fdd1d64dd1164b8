"""Training state, orbax checkpoints and the trained model a run leaves behind.

Run directory layout (``docs/architecture.md``)::

    run_dir/config.json              the run (model, dataset, resolved TrainConfig: a RunConfig),
                                     normalisation stats, scaling, split and padding budget
    run_dir/checkpoints/last/<step>/ the latest checkpoint (kept: 1)
    run_dir/checkpoints/best/<step>/ the checkpoint with the lowest validation MSE (kept: 1)
    run_dir/metrics.jsonl            one JSON object per epoch (and the NaN-guard event, if any)
    run_dir/loss.png                 loss curves, written at the end

A checkpoint has three orbax items: ``params`` (the model variables: with weight averaging, the
averaged ones), ``train`` (optimiser state, step, RNG key data and, with weight averaging, the
optimiser's own iterate) and ``meta`` (JSON: epoch, position in the epoch's data order, best
validation metric, and the same config / stats / scaling as ``config.json``), so one checkpoint
directory is enough to restore a model. Orbax writes each checkpoint to a temporary directory and
renames it when complete, so a run killed while saving keeps its previous checkpoint.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import orbax.checkpoint as ocp
from flax import struct

from thrombojax.data.scaling import Scaling
from thrombojax.data.splits import Split
from thrombojax.errors import ConfigError
from thrombojax.io.outputs import atomic_write_text
from thrombojax.models.registry import Surrogate, config_from_dict, create_model
from thrombojax.simulator.step import LearnedStep, make_step
from thrombojax.train.config import CHECKPOINTS, RunConfig
from thrombojax.types import NodeType, TargetStats

__all__ = [
    "TrainState",
    "TrainedModel",
    "save_checkpoint",
    "restore_checkpoint",
    "latest_step",
    "load_trained",
    "write_run_config",
    "read_run_config",
    "warm_start",
    "append_log",
    "truncate_log",
]


@struct.dataclass
class TrainState:
    """What changes during training (a pytree).

    Attributes:
        step: ``[]`` int32 optimiser steps done.
        params: model variables (the optimiser's iterate).
        opt_state: optax state.
        average: with weight averaging (``TrainConfig.average_weights``), the running mean of
            ``params`` over the averaged steps, the model a checkpoint holds, validates and
            loads (:attr:`model_params`); ``None`` without it.
    """

    step: jax.Array
    params: Any
    opt_state: Any
    average: Any = None

    @property
    def model_params(self) -> Any:
        """The weights of the model this state stands for: the average when there is one."""
        return self.params if self.average is None else self.average


@dataclasses.dataclass(frozen=True)
class TrainedModel:
    """A trained surrogate with everything needed to run it on a dataset.

    Attributes:
        model: the surrogate (:func:`thrombojax.models.registry.create_model`).
        params: its variables.
        stats: acceleration normalisation statistics (training split, clot nodes).
        scaling: the dataset's isotropic map to [-1, 1] (:class:`thrombojax.data.scaling.Scaling`).
        run: the run's :class:`RunConfig` (model, dataset, resolved training config).
        split: the simulations it was trained, validated and tested on.
        config: the whole ``config.json`` (also the derived data: budget, steps, devices).
    """

    model: Surrogate
    params: Any
    stats: TargetStats
    scaling: Scaling
    run: RunConfig
    split: Split
    config: dict

    @property
    def step(self) -> LearnedStep:
        """The learned step this model was trained as (its surrogate in the run's frame)."""
        return make_step(self.model, self.run.train.frame,
                         float(self.config.get("wall_cutoff", 0.0)),
                         history=self.run.train.history,
                         stop_history_gradient=self.run.train.stop_history_gradient,
                         wall_signed=self.run.train.wall_signed,
                         axis_radius=float(self.config.get("axis_radius", 0.0)),
                         prior_radius=float(self.config.get("prior_radius", 0.0)),
                         lateral_radius=float(self.config.get("lateral_radius", 0.0)),
                         wall_clot_mean=self.run.train.wall_clot_mean,
                         outlet_radius=float(self.config.get("outlet_radius", 0.0)),
                         shape_radius=float(self.config.get("shape_radius", 0.0)),
                         rest_edges=self.run.train.rest_edges,
                         start_speed=getattr(self.run.train, "start_span", 1) * bool(
                             getattr(self.run.train, "start_speed", False)),
                         clearance_radius=float(self.config.get("clearance_radius", 0.0)),
                         section_radius=float(self.config.get("section_radius", 0.0)),
                         centre_pull=float(getattr(self.run.train, "centre_pull", 0.0)),
                         centre_unit=float(self.config.get("centre_unit", 0.0)),
                         centre_tolerance=float(self.config.get("centre_tolerance", 0.0)))


def _manager(directory: pathlib.Path, *, read_only: bool = False) -> ocp.CheckpointManager:
    options = ocp.CheckpointManagerOptions(
        max_to_keep=1, enable_async_checkpointing=False, create=not read_only
    )
    return ocp.CheckpointManager(
        directory.resolve(), options=options, item_names=("params", "train", "meta")
    )


def save_checkpoint(directory: str | pathlib.Path, state: TrainState, rng: jax.Array, meta: dict):
    """Save ``state``, the RNG key and JSON metadata as checkpoint ``state.step`` (keeps one).

    Args:
        directory: e.g. ``run_dir/checkpoints/last``.
        state: the training state (replicated or host arrays).
        rng: the run's base PRNG key (raw ``uint32`` key data).
        meta: JSON-serialisable metadata.
    """
    step = int(jax.device_get(state.step))
    train = {"opt_state": state.opt_state, "step": state.step, "rng": rng}
    if state.average is not None:  # the model is the average; the iterate is for resuming
        train["params"] = state.params
    with _manager(pathlib.Path(directory)) as mngr:
        if step in mngr.all_steps():  # re-saving after a resume: replace it
            mngr.delete(step)
        mngr.save(
            step,
            args=ocp.args.Composite(
                params=ocp.args.StandardSave(state.model_params),
                train=ocp.args.StandardSave(train),
                meta=ocp.args.JsonSave(meta),
            ),
            force=True,
        )
        mngr.wait_until_finished()


def latest_step(directory: str | pathlib.Path) -> int | None:
    """The step of the checkpoint in ``directory``, ``None`` when there is none."""
    directory = pathlib.Path(directory)
    if not directory.is_dir():
        return None
    with _manager(directory, read_only=True) as mngr:
        return mngr.latest_step()


def restore_checkpoint(
    directory: str | pathlib.Path, target: TrainState | None = None, rng_target: Any = None
) -> tuple[Any, Any, dict]:
    """Restore the latest checkpoint of ``directory``.

    Args:
        directory: a checkpoint directory written by :func:`save_checkpoint`.
        target: a state with the right structure (and shardings); ``None`` restores the params
            only (the state slot of the result is then the params).
        rng_target: an example RNG key (structure of the saved key) when ``target`` is given.
    Returns:
        ``(state or params, rng or None, meta)``.
    """
    directory = pathlib.Path(directory)
    step = latest_step(directory)
    if step is None:
        raise ConfigError(f"{directory}: no checkpoint to restore")
    with _manager(directory, read_only=True) as mngr:
        if target is None:
            out = mngr.restore(
                step,
                args=ocp.args.Composite(
                    params=ocp.args.StandardRestore(), meta=ocp.args.JsonRestore()
                ),
            )
            return jax.tree.map(jnp.asarray, out["params"]), None, dict(out["meta"])
        train_target = {"opt_state": target.opt_state, "step": target.step, "rng": rng_target}
        if target.average is not None:
            train_target["params"] = target.params
        out = mngr.restore(
            step,
            args=ocp.args.Composite(
                params=ocp.args.StandardRestore(target.model_params),
                train=ocp.args.StandardRestore(train_target),
                meta=ocp.args.JsonRestore(),
            ),
        )
    train = out["train"]
    if target.average is None:
        state = TrainState(step=train["step"], params=out["params"], opt_state=train["opt_state"])
    else:
        state = TrainState(step=train["step"], params=train["params"],
                           opt_state=train["opt_state"], average=out["params"])
    return state, train["rng"], dict(out["meta"])


def write_run_config(run_dir: str | pathlib.Path, config: dict) -> None:
    """Write ``run_dir/config.json`` (atomically)."""
    atomic_write_text(pathlib.Path(run_dir) / "config.json",
                      json.dumps(config, indent=2, sort_keys=True, default=_json_default))


def read_run_config(run_dir: str | pathlib.Path) -> dict:
    """Read ``run_dir/config.json``; a missing file raises FileNotFoundError naming it."""
    path = pathlib.Path(run_dir) / "config.json"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: not a thrombojax run directory (no config.json)")
    try:
        config = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{path}: corrupt run config (not valid JSON: {err})") from err
    missing = [k for k in ("model", "dataset", "train", "stats", "scaling")
               if not isinstance(config, dict) or k not in config]
    if missing:
        raise ConfigError(f"{path}: corrupt or foreign run config, missing {missing}")
    return config


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray | jax.Array):
        return np.asarray(value).tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def load_trained(run_dir: str | pathlib.Path, *, which: str = "best") -> TrainedModel:
    """Load a trained model from a run directory.

    Args:
        run_dir: the ``--out`` directory of ``thrombojax train``.
        which: ``"best"`` (lowest validation MSE) or ``"last"``.
    Returns:
        The :class:`TrainedModel`.
    """
    if which not in CHECKPOINTS:
        raise ConfigError(f"which must be one of {list(CHECKPOINTS)}, got {which!r}")
    run_dir = pathlib.Path(run_dir)
    config = read_run_config(run_dir)
    ckpt = run_dir / "checkpoints" / which
    if latest_step(ckpt) is None:
        raise ConfigError(f"{run_dir}: no '{which}' checkpoint in {ckpt}")
    try:
        params, _, meta = restore_checkpoint(ckpt)
    except ConfigError:
        raise
    except Exception as err:  # orbax / tensorstore errors on truncated or bit-flipped files
        first = " ".join(str(err).split())[:200]
        raise ConfigError(f"{ckpt}: checkpoint cannot be read (corrupt or incomplete run "
                          f"folder): {type(err).__name__}: {first}") from err
    config_path = run_dir / "config.json"
    try:
        run = RunConfig.from_dict(config)
        split = Split.from_dict(config.get("split", {}))
    except ConfigError as err:
        raise ConfigError(f"{config_path}: {err}") from err
    if isinstance(meta, dict) and meta.get("model", run.model) != run.model:
        raise ConfigError(f"{run_dir}: config.json is for model '{run.model}' but the "
                          f"'{which}' checkpoint is a '{meta.get('model')}' run")
    if not all(bool(jnp.isfinite(x).all()) for x in jax.tree.leaves(params)):
        raise ConfigError(f"{ckpt}: checkpoint holds NaN or infinite weights; not usable")
    try:
        model = create_model(run.model, config_from_dict(run.model, run.train.model_config))
        trained = TrainedModel(
            model=model, params=params, stats=TargetStats.from_dict(config["stats"]),
            scaling=Scaling.from_dict(config["scaling"]), run=run, split=split, config=config,
        )
    except (KeyError, TypeError, ValueError) as err:
        if isinstance(err, ConfigError):
            raise
        raise ConfigError(f"{config_path}: does not match the run's checkpoint "
                          f"({type(err).__name__}: {err})") from err
    _check_params_fit(trained, config_path, ckpt)
    return trained


def warm_start(state: TrainState, tx: Any, run_dir: str | pathlib.Path, which: str,
               model_name: str) -> TrainState:
    """Start a training from another run's weights (fine-tuning): ``state`` (a fresh
    :class:`TrainState`) with its params replaced by those of ``run_dir``'s ``which``
    checkpoint and a fresh optimiser state for them, at step 0.

    The other run must be of the same model with the same parameter shapes (the same model
    config and the same step inputs); anything else is a :class:`ConfigError` naming both.
    """
    try:
        trained = load_trained(run_dir, which=which)
    except (FileNotFoundError, ConfigError) as err:
        raise ConfigError(f"--init-from {run_dir}: {err}") from err
    if trained.run.model != model_name:
        raise ConfigError(f"--init-from {run_dir}: a '{trained.run.model}' run; this training "
                          f"is of '{model_name}'")
    want, got = _shapes(state.params), _shapes(trained.params)
    if want != got:
        diff = sorted(k for k in set(want) | set(got) if want.get(k) != got.get(k))[:3]
        raise ConfigError(f"--init-from {run_dir}: its '{which}' weights do not fit this "
                          f"training's model (other model config or step inputs?); e.g. "
                          + ", ".join(f"{k}: {got.get(k)} there, {want.get(k)} here"
                                      for k in diff))
    params = jax.tree.map(lambda x, like: jnp.asarray(x, like.dtype), trained.params,
                          state.params)
    return TrainState(step=jnp.zeros((), jnp.int32), params=params, opt_state=tx.init(params),
                      average=None if state.average is None else jax.tree.map(jnp.copy, params))


def append_log(out_dir: pathlib.Path, record: dict) -> None:
    """Append one JSON line to ``out_dir/metrics.jsonl`` (process 0 only)."""
    if jax.process_index() != 0:
        return
    with open(out_dir / "metrics.jsonl", "a") as f:
        f.write(json.dumps(record) + "\n")


def truncate_log(path: pathlib.Path, step: int) -> None:
    """Drop log lines written after the checkpoint we resume from."""
    if not path.is_file():
        return
    lines = [ln for ln in path.read_text().splitlines() if ln.strip()]
    keep = [ln for ln in lines if json.loads(ln).get("step", 0) <= step]
    path.write_text("".join(ln + "\n" for ln in keep))


def _shapes(tree) -> dict:
    flat = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {jax.tree_util.keystr(k): tuple(v.shape) for k, v in flat}


def _check_params_fit(trained: TrainedModel, config_path: pathlib.Path, ckpt: pathlib.Path) -> None:
    """The checkpoint's parameter tree must be the one the config's model creates."""
    n = 8
    pos = jnp.zeros((n, 3), jnp.float32) + jnp.linspace(0, 0.1, n)[:, None]
    node_type = jnp.full(n, NodeType.CLOT, jnp.int32)
    init = trained.step.init
    try:
        want = jax.eval_shape(lambda: init(jax.random.key(0), pos, pos, node_type,
                                           jnp.ones(n, bool)))
    except Exception:  # noqa: BLE001  a model whose init needs more than this: skip the check
        return

    if _shapes(trained.params) != _shapes(want):
        raise ConfigError(f"{ckpt}: the checkpoint's weights do not fit the model described by "
                          f"{config_path} (a config.json from another run or model?)")
