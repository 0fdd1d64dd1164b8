"""Experiment config files: one TOML file per experiment, three scales each, typed on load.

A file (``experiments/configs/<name>.toml``) holds the experiment's identity and one table per
scale (``smoke``, ``cpu``, ``study``)::

    name = "rotation_sweep"
    title = "Rotation sweep per model"
    reproduces = "which result of the study, and where its numbers are"
    kind = "sweep"            # sweep | seeds | rollout | generalisation | ladder | timing | search
    sweep = "max_rotation"    # the TrainConfig field a sweep varies

    [smoke]
    datasets = ["bendvessel-tiny"]     # solver presets (thrombojax/sim/presets.py)
    models = ["mgn"]
    seeds = [0, 1]
    values = [0.0, "pi"]               # sweep values (ladder: rung tables)
    step_s = {mgn = 0.05}              # seconds per training step, for the cost estimate
    step_s_source = "how step_s was measured"
    [smoke.train]                      # TrainConfig keys (thrombojax/train/config.py)
    epochs = 1
    tiny = true
    [smoke.model_config.mgn]           # model config overrides of one model
    hidden = 32
    [smoke.options]                    # kind-specific settings (bench sizes, search space)

Every scale's ``train`` table is loaded into :class:`thrombojax.train.config.TrainConfig` when
the file is read, so a bad key or value fails before anything runs, naming the file and the
field. ``--set KEY=VALUE`` (:func:`apply_sets`) overrides any field of the chosen scale:
``train.epochs=5``, ``train.model_config.hidden=64``, ``models=["mgn","erwin"]``, ``seeds=3``.
"""

from __future__ import annotations

import copy
import dataclasses
import pathlib
import tomllib
from collections.abc import Mapping, Sequence
from typing import Any

from thrombojax.errors import ConfigError
from thrombojax.models.registry import get_config
from thrombojax.train.config import TrainConfig

__all__ = [
    "KINDS",
    "SCALES",
    "Scale",
    "Experiment",
    "load_experiment",
    "apply_sets",
    "config_dir",
    "find_experiment",
    "list_experiments",
]

KINDS = ("sweep", "seeds", "rollout", "generalisation", "ladder", "timing", "search")
SCALES = ("smoke", "cpu", "study")
_SCALE_KEYS = {"datasets", "models", "seeds", "values", "train", "model_config", "per_dataset",
               "options", "step_s", "step_s_source"}


@dataclasses.dataclass(frozen=True)
class Scale:
    """One size of an experiment.

    Attributes:
        datasets: solver presets whose datasets the runs train on (generated on demand).
        models: registry names of the surrogates.
        seeds: training seeds; results are aggregated over them (mean +- std).
        values: the values of the swept field (sweeps, generalisation), or the ladder's rungs
            (tables with ``name``, ``train`` overrides and ``guards``: a list of booleans).
        train: the training config every run starts from.
        model_config: model -> overrides of its model config (merged into
            ``train.model_config`` for that model's runs).
        per_dataset: preset -> TrainConfig overrides of that dataset's runs (ClotEntry's
            ``nodes_per_sample = 2048``).
        options: kind-specific settings (``bench`` sizes of a timing, ``trials`` and ``space``
            of a search, ``rollout_steps`` of a rollout).
        step_s: seconds per training step per model (the cost estimate; missing: unknown).
        step_s_source: where ``step_s`` comes from (measured how, on what).
    """

    datasets: tuple[str, ...]
    models: tuple[str, ...]
    seeds: tuple[int, ...]
    values: tuple[Any, ...]
    train: TrainConfig
    model_config: dict
    per_dataset: dict
    options: dict
    step_s: dict
    step_s_source: str = ""


@dataclasses.dataclass(frozen=True)
class Experiment:
    """An experiment: what it reproduces and its three scales.

    Attributes:
        name: file stem and CLI name. title: one line. reproduces: the study's result it
            reproduces. kind: how runs are made and measured (:data:`KINDS`).
        sweep: the TrainConfig field a sweep varies (``None`` for other kinds).
        scales: ``smoke``, ``cpu``, ``study`` -> :class:`Scale`.
        path: the file it was read from. raw: the parsed TOML (``--set`` edits a copy of it).
    """

    name: str
    title: str
    reproduces: str
    kind: str
    sweep: str | None
    scales: Mapping[str, Scale]
    path: str
    raw: dict = dataclasses.field(repr=False, compare=False, default_factory=dict)

    def scale(self, name: str) -> Scale:
        """The scale called ``name``; an unknown one raises :class:`ConfigError`."""
        if name not in self.scales:
            raise ConfigError(f"{self.path}: no scale '{name}'; scales: {list(self.scales)}")
        return self.scales[name]


def _tuple(value: Any, where: str, kind: type) -> tuple:
    if isinstance(value, kind):  # seeds = 3 means seeds 0, 1, 2
        value = list(range(value)) if kind is int else [value]
    if not isinstance(value, list | tuple):
        raise ConfigError(f"{where}: must be a list, got {value!r}")
    if not all(isinstance(v, kind) and not isinstance(v, bool) for v in value):
        raise ConfigError(f"{where}: every entry must be a {kind.__name__}, got {value!r}")
    return tuple(value)


def _check_model_config(model: str, fields: dict, where: str, tiny: bool) -> None:
    """Unknown models and fields fail when the file is read, not in the middle of a sweep."""
    try:
        get_config(model, tiny=tiny, **fields)
    except (ConfigError, TypeError, ValueError) as err:
        raise ConfigError(f"{where}: {err}") from err


def _scale(raw: Any, where: str, kind: str) -> Scale:
    if not isinstance(raw, dict):
        raise ConfigError(f"{where}: must be a table")
    unknown = sorted(set(raw) - _SCALE_KEYS)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown}; known: {sorted(_SCALE_KEYS)}")
    try:
        train = TrainConfig.from_dict(dict(raw.get("train", {})))
    except (ConfigError, TypeError) as err:
        raise ConfigError(f"{where}.train: {err}") from err
    datasets = _tuple(raw.get("datasets", []), f"{where}.datasets", str)
    models = _tuple(raw.get("models", []), f"{where}.models", str)
    seeds = _tuple(raw.get("seeds", [0]), f"{where}.seeds", int)
    if not datasets and kind != "timing":
        raise ConfigError(f"{where}.datasets: name at least one dataset preset")
    if not models:
        raise ConfigError(f"{where}.models: name at least one model")
    if not seeds or min(seeds) < 0:
        raise ConfigError(f"{where}.seeds: at least one seed, all >= 0")
    values = raw.get("values", [])
    if not isinstance(values, list):
        raise ConfigError(f"{where}.values: must be a list")
    step_s = raw.get("step_s", {})
    if isinstance(step_s, int | float):
        step_s = {m: float(step_s) for m in models}
    if not isinstance(step_s, dict) or not all(isinstance(v, int | float) and v > 0
                                               for v in step_s.values()):
        raise ConfigError(f"{where}.step_s: a table of positive seconds per model")
    options = raw.get("options", {})
    if not isinstance(options, dict):
        raise ConfigError(f"{where}.options: must be a table")
    model_config = raw.get("model_config", {})
    if not isinstance(model_config, dict) or not all(isinstance(v, dict)
                                                     for v in model_config.values()):
        raise ConfigError(f"{where}.model_config: a table of tables, one per model")
    per_dataset = raw.get("per_dataset", {})
    if not isinstance(per_dataset, dict) or not all(isinstance(v, dict)
                                                    for v in per_dataset.values()):
        raise ConfigError(f"{where}.per_dataset: a table of tables, one per dataset preset")
    for preset, fields in per_dataset.items():
        try:
            train.replace(**fields)
        except (ConfigError, TypeError) as err:
            raise ConfigError(f"{where}.per_dataset.{preset}: {err}") from err
    for model in models:
        _check_model_config(model, {**train.model_config, **model_config.get(model, {})},
                            f"{where}.model_config.{model}", train.tiny)
    return Scale(datasets=datasets, models=models, seeds=seeds, values=tuple(values),
                 train=train, model_config=dict(model_config),
                 per_dataset=dict(per_dataset), options=dict(options), step_s=dict(step_s),
                 step_s_source=str(raw.get("step_s_source", "")))


def _experiment(raw: dict, path: str) -> Experiment:
    kind = raw.get("kind")
    if kind not in KINDS:
        raise ConfigError(f"{path}: kind must be one of {list(KINDS)}, got {kind!r}")
    for key in ("name", "title", "reproduces"):
        if not isinstance(raw.get(key), str) or not raw[key]:
            raise ConfigError(f"{path}: '{key}' must be a non-empty string")
    sweep = raw.get("sweep")
    if kind == "sweep":
        known = {f.name for f in dataclasses.fields(TrainConfig)}
        if sweep not in known:
            raise ConfigError(f"{path}: sweep must name a TrainConfig field, got {sweep!r}")
    missing = [s for s in SCALES if s not in raw]
    if missing:
        raise ConfigError(f"{path}: missing scale table(s) {missing}")
    scales = {s: _scale(raw[s], f"{path}: [{s}]", kind) for s in SCALES}
    for s, scale in scales.items():
        if kind in ("sweep", "generalisation", "ladder") and not scale.values:
            raise ConfigError(f"{path}: [{s}].values: a {kind} needs at least one value")
    return Experiment(name=raw["name"], title=raw["title"], reproduces=raw["reproduces"],
                      kind=kind, sweep=sweep, scales=scales, path=path, raw=raw)


def load_experiment(path: str | pathlib.Path) -> Experiment:
    """Read and check an experiment file (every scale's ``train`` becomes a TrainConfig)."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: experiment file not found")
    try:
        raw = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML: {err}") from err
    return _experiment(raw, str(path))


def _parse_value(text: str) -> Any:
    """A TOML value (``5``, ``1e-3``, ``true``, ``["mgn", "erwin"]``), else the bare string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_sets(experiment: Experiment, scale: str, sets: Sequence[str]) -> Experiment:
    """The experiment with ``KEY=VALUE`` overrides applied to one scale (``--set``).

    ``KEY`` is a dotted path inside the scale's table (``train.epochs``,
    ``train.model_config.hidden``, ``models``, ``options.trials``); ``VALUE`` is read as TOML,
    a bare word as a string. The edited scale is checked as when the file is read.
    """
    if not sets:
        return experiment
    raw = copy.deepcopy(experiment.raw)
    table = raw.setdefault(scale, {})
    for item in sets:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set expects KEY=VALUE, got '{item}'")
        parts = key.strip().split(".")
        if parts[0] not in _SCALE_KEYS:
            raise ConfigError(f"--set {key}: unknown key '{parts[0]}'; known: "
                              f"{sorted(_SCALE_KEYS)}")
        node = table
        for part in parts[:-1]:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"--set {key}: '{part}' is not a table")
        node[parts[-1]] = _parse_value(text.strip())
    try:
        return _experiment(raw, experiment.path)
    except ConfigError as err:
        raise ConfigError(f"--set: {err}") from err


def config_dir() -> pathlib.Path:
    """``experiments/configs`` of the source tree (beside the package), else of the cwd."""
    here = pathlib.Path(__file__).resolve().parents[2] / "experiments" / "configs"
    return here if here.is_dir() else pathlib.Path.cwd() / "experiments" / "configs"


def list_experiments(folder: str | pathlib.Path | None = None) -> list[Experiment]:
    """Every experiment file (``*.toml``) of ``folder`` (default :func:`config_dir`), by name."""
    folder = pathlib.Path(folder) if folder else config_dir()
    return [load_experiment(p) for p in sorted(folder.glob("*.toml"))]


def find_experiment(name: str, folder: str | pathlib.Path | None = None) -> Experiment:
    """An experiment by name (a file in ``folder``) or by the path of its TOML file."""
    if name.endswith(".toml"):
        return load_experiment(name)
    folder = pathlib.Path(folder) if folder else config_dir()
    path = folder / f"{name}.toml"
    if not path.is_file():
        known = sorted(p.stem for p in folder.glob("*.toml"))
        raise ConfigError(f"unknown experiment '{name}' (no {path}); known: {known}")
    return load_experiment(path)
