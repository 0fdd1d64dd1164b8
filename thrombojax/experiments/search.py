"""Bayesian hyper-parameter search with Optuna (an optional extra: ``thrombojax[experiments]``).

TPE sampler; a trial reports its validation MSE after every epoch (read from the run's
``metrics.jsonl`` in the training loop's callback) and a :class:`optuna.pruners.MedianPruner`
stops it early (:class:`optuna.TrialPruned`). The study lives in SQLite
(``sqlite:///DIR/search.db``) by default, so a killed search resumes where it stopped; any RDB
URL (``--storage postgresql://...``) lets several processes or hosts share one study (each
runs trials until the study holds ``trials`` finished ones). Trials whose process died are
marked failed by Optuna's heartbeat and retried once.

The space is the scale's ``options.space`` (``experiments/configs/hyperparameter_search.toml``):
each entry a TrainConfig field, or ``model_config.<field>``, with ``type`` ``log_float``
(``low``, ``high``), ``float``, ``int`` or ``categorical`` (``choices``). The best trial's
training config is exported to ``DIR/best_config.json``, which ``thrombojax train --config``
reads.
"""

from __future__ import annotations

import json
import pathlib
from collections.abc import Mapping

import matplotlib.pyplot as plt

from thrombojax import study as study_numbers
from thrombojax.errors import ConfigError, OutputError
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.experiments.data import ensure_dataset
from thrombojax.experiments.execute import train_run
from thrombojax.experiments.plan import plan_runs
from thrombojax.experiments.runner import prepare_folder
from thrombojax.experiments.spec import Experiment
from thrombojax.io.outputs import atomic_path, atomic_write_text
from thrombojax.models.registry import config_to_dict, get_config
from thrombojax.train.config import TrainConfig

__all__ = ["suggest", "run_search"]


def suggest(trial, space: Mapping[str, Mapping], base: TrainConfig) -> TrainConfig:
    """The trial's training config: ``base`` with every dimension of ``space`` sampled."""
    changes: dict = {}
    model_config = dict(base.model_config)
    for name, dim in space.items():
        kind = dim.get("type")
        if kind == "log_float":
            value = trial.suggest_float(name, float(dim["low"]), float(dim["high"]), log=True)
        elif kind == "float":
            value = trial.suggest_float(name, float(dim["low"]), float(dim["high"]))
        elif kind == "int":
            value = trial.suggest_int(name, int(dim["low"]), int(dim["high"]))
        elif kind == "categorical":
            value = trial.suggest_categorical(name, list(dim["choices"]))
        else:
            raise ConfigError(f"search space '{name}': type must be log_float, float, int or "
                              f"categorical, got {kind!r}")
        if name.startswith("model_config."):
            model_config[name.split(".", 1)[1]] = value
        else:
            changes[name] = value
    return base.replace(**changes, model_config=model_config)


def _pruning_callback(trial, folder: pathlib.Path):
    """Report each new epoch's validation MSE; raise TrialPruned when the pruner says so."""
    import optuna

    log, seen = folder / "metrics.jsonl", {"epoch": 0, "size": -1}

    def callback(step: int, metrics: dict) -> None:
        size = log.stat().st_size
        if size == seen["size"]:  # no new epoch record since the last step
            return
        seen["size"] = size
        lines = [json.loads(ln) for ln in log.read_text().splitlines() if ln.strip()]
        for rec in lines:
            if rec.get("epoch", 0) > seen["epoch"] and "event" not in rec:
                seen["epoch"] = rec["epoch"]
                trial.report(rec.get("val_mse", rec["train_mse"]), rec["epoch"])
                if trial.should_prune():
                    raise optuna.TrialPruned(f"pruned at epoch {rec['epoch']}")

    return callback


def _best_score(folder: pathlib.Path) -> float:
    recs = [json.loads(ln) for ln in (folder / "metrics.jsonl").read_text().splitlines()
            if ln.strip()]
    return min(r.get("val_mse", r.get("train_mse", float("inf"))) for r in recs if "epoch" in r
               and "event" not in r)


def _storage(url: str):
    """An RDB storage with a heartbeat: trials of a killed process are failed and retried once
    (Optuna >= 4.9 names the callback ``heartbeat_stale_trial_callback``)."""
    import warnings

    import optuna
    from optuna import storages

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        warnings.simplefilter("ignore", FutureWarning)
        if hasattr(storages, "RetryHeartbeatStaleTrialCallback"):
            return storages.RDBStorage(
                url, heartbeat_interval=60, grace_period=180,
                heartbeat_stale_trial_callback=storages.RetryHeartbeatStaleTrialCallback(1))
        return storages.RDBStorage(url, heartbeat_interval=60, grace_period=180,
                                   failed_trial_callback=storages.RetryFailedTrialCallback(1))


def run_search(experiment: Experiment, scale: str, out: str | pathlib.Path, *,
               storage: str | None = None, trials: int | None = None, force: bool = False,
               progress: bool = False, data_dir=None, datasets=None, log=print) -> dict:
    """Run (or resume) the search until the study holds ``trials`` finished trials.

    Returns:
        ``{"best_config": path, "best_value", "report": {"table", "files"}}``.
    """
    try:
        import optuna
    except ImportError:
        raise ConfigError("the search needs Optuna: pip install 'thrombojax[experiments]'"
                          ) from None
    out = pathlib.Path(out)
    sc = experiment.scale(scale)
    space = sc.options.get("space")
    if not isinstance(space, dict) or not space:
        raise ConfigError(f"{experiment.path}: [{scale}.options.space]: the search space is "
                          "missing")
    n_trials = int(trials or sc.options.get("trials", 20))
    run = plan_runs(experiment, scale)[0]  # the first dataset, model and seed
    prepare_folder(out, experiment, scale, force=force)
    data = ensure_dataset(run.dataset, pathlib.Path(data_dir) if data_dir else out / "data",
                          given=datasets, progress=progress)
    url = storage or f"sqlite:///{(out / 'search.db').resolve()}"
    name = f"{experiment.name}-{scale}"
    try:
        store = _storage(url)
    except Exception as err:  # noqa: BLE001 - SQLAlchemy's errors for a bad URL vary
        raise ConfigError(f"--storage {url}: cannot open the Optuna storage: {err}") from err
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    if force and name in optuna.get_all_study_names(store):
        optuna.delete_study(study_name=name, storage=store)
    pruner = optuna.pruners.MedianPruner(
        n_startup_trials=int(sc.options.get("startup_trials", 5)),
        n_warmup_steps=int(sc.options.get("warmup_epochs", 1)))
    opt = optuna.create_study(study_name=name, storage=store, direction="minimize",
                              sampler=optuna.samplers.TPESampler(seed=run.seed),
                              pruner=pruner, load_if_exists=True)

    def objective(trial) -> float:
        cfg = suggest(trial, space, run.train)
        folder = out / "trials" / f"trial_{trial.number:04d}"
        if (folder / "config.json").is_file() and not force:  # numbers are unique per study
            raise OutputError(f"{folder}: holds a trial of an earlier study (another storage, "
                              "or one deleted); use another --out, or --force")
        log(f"trial {trial.number}: {trial.params}")
        train_run(run, cfg, folder, data, force=True, progress=progress,
                  callback=_pruning_callback(trial, folder))
        return _best_score(folder)

    done = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    if len(opt.get_trials(deepcopy=False, states=done)) < n_trials:
        opt.optimize(objective, callbacks=[optuna.study.MaxTrialsCallback(n_trials, states=done)],
                     catch=())
    return _report(experiment, scale, opt, run, out)


def _report(experiment: Experiment, scale: str, opt, run, out: pathlib.Path) -> dict:
    """Trials table, the best beside the study's choice, history plot, best_config.json."""
    import optuna

    trials = [t for t in opt.trials if t.state in (optuna.trial.TrialState.COMPLETE,
                                                    optuna.trial.TrialState.PRUNED)]
    complete = [t for t in trials if t.state == optuna.trial.TrialState.COMPLETE]
    if not complete:
        raise ConfigError(f"{out}: no trial of the search finished unpruned")
    best = opt.best_trial
    best_cfg = suggest(optuna.trial.FixedTrial(best.params), experiment.scale(scale)
                       .options["space"], run.train)
    model_cfg = config_to_dict(get_config(run.model, tiny=best_cfg.tiny,
                                          **best_cfg.model_config))
    best_cfg = best_cfg.replace(model_config=model_cfg)
    atomic_write_text(out / "best_config.json", json.dumps(best_cfg.to_dict(), indent=2))
    names = sorted({k for t in trials for k in t.params})
    rows = [[t.number, t.state.name.lower(), *[t.params.get(k, "-") for k in names],
             "-" if t.value is None else t.value] for t in trials]
    table = markdown_table(["trial", "state", *names, "best validation MSE"], rows)
    ref = {"lr": study_numbers.training_defaults(run.model)["lr"],
           "batch_size": study_numbers.training_defaults(run.model)["batch_size"],
           **{f"model_config.{k}": v for k, v in config_to_dict(get_config(run.model)).items()}}
    side = markdown_table(["hyper-parameter", "best trial", "study's choice"],
                          [[k, best.params[k], ref.get(k, "-")] for k in names])
    fig, ax = plt.subplots(figsize=(6, 4))
    xs = [t.number for t in complete]
    ys = [t.value for t in complete]
    ax.plot(xs, ys, "o", label="trial")
    ax.plot(xs, [min(ys[: i + 1]) for i in range(len(ys))], "-", label="best so far")
    ax.set_yscale("log")
    ax.set_xlabel("trial")
    ax.set_ylabel("best validation MSE")
    ax.set_title(experiment.title)
    ax.legend()
    fig.tight_layout()
    with atomic_path(out / "history.png") as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    env = environment()
    text = (f"# {experiment.title} ({scale} scale)\n\nReproduces: {experiment.reproduces}\n\n"
            f"{table}\nBest trial {best.number} (validation MSE {best.value:.4g}) beside the "
            f"study's settings of {run.model}:\n\n{side}\nBest config: best_config.json "
            f"(thrombojax train --config {out / 'best_config.json'} --model {run.model} ...)\n\n"
            + "".join(f"- {k}: {v}\n" for k, v in env.items()))
    atomic_write_text(out / "table.md", text)
    files = [out / "table.md", out / "best_config.json", out / "history.png"]
    return {"best_config": str(out / "best_config.json"), "best_value": best.value,
            "report": {"table": table, "files": [str(f) for f in files]}}
