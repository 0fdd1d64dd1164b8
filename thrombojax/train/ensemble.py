"""Deep ensembles: M training runs that differ only by seed, and loading them as one model.

:func:`train_ensemble` calls :func:`thrombojax.train.loop.train` once per member, with the seed
``seed + i`` (initialisation, data order, augmentations; the split seed is the config's, so every
member trains on the same simulations and has the same statistics), into::

    out_dir/ensemble.json     {"members": ["member_0", ...], "seeds": [...], "model": ...}
    out_dir/member_<i>/       an ordinary run directory (thrombojax.train.state)

:func:`load_ensemble` loads every member with :func:`thrombojax.train.state.load_trained`, checks
they share the model and its config, the statistics, the scaling and the split (a
:class:`ConfigError` naming the member otherwise), and stacks their parameters for
:func:`thrombojax.simulator.ensemble.ensemble_rollout`. :func:`join_ensemble` makes an ensemble
folder of runs trained one by one (``thrombojax ensemble``): its manifest lists their absolute
paths, and nothing is written into the runs.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
import re
import warnings
from typing import Any

from thrombojax.data.scaling import Scaling
from thrombojax.data.splits import Split
from thrombojax.errors import ConfigError
from thrombojax.io.outputs import atomic_write_text
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.ensemble import stack_params
from thrombojax.simulator.step import LearnedStep
from thrombojax.train.config import RunConfig
from thrombojax.train.loop import train
from thrombojax.train.state import TrainedModel, latest_step, load_trained
from thrombojax.types import TargetStats

__all__ = ["MANIFEST", "TrainedEnsemble", "member_dirs", "train_ensemble", "load_ensemble",
           "join_ensemble"]

MANIFEST = "ensemble.json"
_MEMBER = re.compile(r"^member_(\d+)$")


@dataclasses.dataclass(frozen=True)
class TrainedEnsemble:
    """M trained members of one surrogate, ready for an ensemble rollout.

    Attributes:
        model: the surrogate every member shares.
        params: the members' parameters stacked, leaves ``[M, ...]`` (:func:`stack_params`).
        stats: the shared target statistics. scaling: the shared dataset scaling.
        run: member 0's :class:`RunConfig` (the members differ only in ``train.seed``).
        split: the shared split.
        members: the M :class:`TrainedModel` objects, in member order.
        directories: the M member run directories.
    """

    model: Surrogate
    params: Any
    stats: TargetStats
    scaling: Scaling
    run: RunConfig
    split: Split
    members: tuple[TrainedModel, ...]
    directories: tuple[pathlib.Path, ...]

    @property
    def n_members(self) -> int:
        """M."""
        return len(self.members)

    @property
    def step(self) -> LearnedStep:
        """The learned step every member was trained as (the surrogate in the run's frame)."""
        return self.members[0].step

    @property
    def seeds(self) -> list[int]:
        """Each member's training seed."""
        return [m.run.train.seed for m in self.members]


def train_ensemble(
    dataset_path: str | pathlib.Path | None,
    model_name: str | None,
    out_dir: str | pathlib.Path,
    n_members: int,
    *,
    seed: int = 0,
    resume: bool = False,
    **train_kwargs: Any,
) -> TrainedEnsemble:
    """Train ``n_members`` runs that differ only by seed, then load them as an ensemble.

    Args:
        dataset_path, model_name: as :func:`thrombojax.train.loop.train`.
        out_dir: the ensemble directory; member i goes to ``out_dir/member_<i>``.
        n_members: M >= 1.
        seed: member i trains with seed ``seed + i`` (replaces any seed of ``config``).
        resume: continue members that have a run directory, start the others.
        **train_kwargs: passed to every :func:`train` call unchanged (``config``, ``progress``,
            ``force``, training options such as ``epochs``); not ``seed``.
    Returns:
        :func:`load_ensemble` of ``out_dir`` (best checkpoints).
    """
    if int(n_members) < 1:
        raise ConfigError(f"train_ensemble: n_members must be >= 1, got {n_members}")
    if "seed" in train_kwargs:
        raise ConfigError("train_ensemble: pass the base seed as seed=; member i uses seed + i")
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = [f"member_{i}" for i in range(int(n_members))]
    seeds = [int(seed) + i for i in range(int(n_members))]
    manifest = {"members": names, "seeds": seeds, "model": model_name,
                "dataset": None if dataset_path is None else str(dataset_path)}
    atomic_write_text(out_dir / MANIFEST, json.dumps(manifest, indent=2))
    for name, member_seed in zip(names, seeds, strict=True):
        member = out_dir / name
        started = (member / "config.json").is_file()
        train(dataset_path, model_name, member, resume=resume and started, seed=member_seed,
              **train_kwargs)
    return load_ensemble(out_dir)


def member_dirs(ensemble_dir: str | pathlib.Path) -> list[pathlib.Path]:
    """The member run directories of an ensemble, in member order: those the manifest
    (``ensemble.json``) lists (relative to the folder, or absolute paths as
    :func:`join_ensemble` writes them), else every ``member_<i>`` folder sorted by ``i``."""
    ensemble_dir = pathlib.Path(ensemble_dir)
    manifest = ensemble_dir / MANIFEST
    if manifest.is_file():
        try:
            names = json.loads(manifest.read_text())["members"]
        except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError) as err:
            raise ConfigError(f"{manifest}: corrupt ensemble manifest ({err})") from err
        return [ensemble_dir / str(n) for n in names]
    found = [(int(m.group(1)), p) for p in ensemble_dir.iterdir() if p.is_dir()
             and (m := _MEMBER.match(p.name))] if ensemble_dir.is_dir() else []
    return [p for _, p in sorted(found)]


def _signature(trained: TrainedModel) -> dict[str, Any]:
    """What members must share: the model, its config, statistics, scaling, split."""
    return {
        "model": trained.run.model,
        "model config": trained.run.train.model_config,
        "statistics": trained.stats.to_dict(),
        "scaling": trained.scaling.to_dict(),
        "split": trained.split.to_dict(),
    }


def load_ensemble(ensemble_dir: str | pathlib.Path, *, which: str = "best") -> TrainedEnsemble:
    """Load every member of an ensemble directory and stack their parameters.

    Args:
        ensemble_dir: the ``out_dir`` of :func:`train_ensemble` (or any folder of
            ``member_<i>`` run directories).
        which: ``"best"`` or ``"last"`` checkpoint of each member.
    Returns:
        The :class:`TrainedEnsemble`.
    Raises:
        ConfigError: no members, a member without a checkpoint, or a member whose model, model
            config, statistics, scaling or split differ from member 0's (one line naming it).
    """
    ensemble_dir = pathlib.Path(ensemble_dir)
    dirs = member_dirs(ensemble_dir)
    if not dirs:
        raise ConfigError(f"{ensemble_dir}: not an ensemble (no {MANIFEST} and no member_<i> "
                          "run directories)")
    return _load_members(ensemble_dir, dirs, which)


def _load_members(where: pathlib.Path, dirs: list[pathlib.Path], which: str) -> TrainedEnsemble:
    """Load the runs ``dirs`` as one ensemble, checking that they differ only by seed."""
    members = []
    for d in dirs:
        if latest_step(d / "checkpoints" / which) is None:
            raise ConfigError(f"{d}: ensemble member has no '{which}' checkpoint (not trained "
                              "yet? train_ensemble(..., resume=True) finishes it)")
        members.append(load_trained(d, which=which))
    ref = _signature(members[0])
    for d, member in zip(dirs[1:], members[1:], strict=True):
        sig = _signature(member)
        differ = [k for k in ref if sig[k] != ref[k]]
        if differ:
            first = dirs[0].name if dirs[0].parent == d.parent else dirs[0]
            raise ConfigError(f"{d}: ensemble member differs from {first} in "
                              f"{', '.join(differ)}; members must differ only by seed")
    try:
        params = stack_params([m.params for m in members])
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from err
    first = members[0]
    return TrainedEnsemble(model=first.model, params=params, stats=first.stats,
                           scaling=first.scaling, run=first.run, split=first.split,
                           members=tuple(members), directories=tuple(dirs))


def join_ensemble(runs: list[str | pathlib.Path], out_dir: str | pathlib.Path, *,
                  which: str = "best", force: bool = False) -> TrainedEnsemble:
    """Join runs trained one by one into an ensemble folder that ``thrombojax rollout`` reads.

    The runs are checked as :func:`load_ensemble` checks members (the same model, model config,
    statistics, scaling and split; a ``which`` checkpoint each) before anything is written.
    Then ``out_dir/ensemble.json`` lists the runs' absolute paths and seeds; the runs
    themselves are not touched and are not copied, so moving them breaks the ensemble.

    Args:
        runs: two or more run directories (``thrombojax train --out``), in member order.
        out_dir: the ensemble folder (made if missing).
        which: the checkpoint every run must have (``"best"`` or ``"last"``); a rollout may
            still ask for the other one.
        force: replace an existing ``ensemble.json`` in ``out_dir``.
    Returns:
        The joined :class:`TrainedEnsemble` (``which`` checkpoints).
    Raises:
        ConfigError: fewer than two runs, a run listed twice, a path that is not a run, runs
            that differ in more than the seed, an ``out_dir`` inside a run or holding trained
            members, or an existing manifest without ``force``.
    """
    dirs = [pathlib.Path(r).resolve() for r in runs]
    out_dir = pathlib.Path(out_dir).resolve()
    if len(dirs) < 2:
        raise ConfigError(f"join_ensemble: an ensemble needs two or more runs, got {len(dirs)}")
    for i, d in enumerate(dirs):
        if not (d / "config.json").is_file():
            raise ConfigError(f"{d}: not a training run (no config.json)")
        if d in dirs[:i]:
            raise ConfigError(f"{d}: listed twice; each run joins the ensemble once")
        if out_dir == d or d in out_dir.parents:
            raise ConfigError(f"{out_dir}: inside the run {d}; the ensemble folder must not be "
                              "written into a run")
    if (out_dir / "config.json").is_file() or _holds_members(out_dir):
        raise ConfigError(f"{out_dir}: holds a run or trained ensemble members; join into a "
                          "new folder")
    manifest = out_dir / MANIFEST
    if manifest.exists() and not force:
        raise ConfigError(f"{manifest} exists; pass force=True (--force) to replace it")
    ens = _load_members(out_dir, dirs, which)
    seen: dict[int, pathlib.Path] = {}
    for d, seed in zip(dirs, ens.seeds, strict=True):
        if seed in seen:
            warnings.warn(f"{d} and {seen[seed]} were trained with the same seed {seed}: "
                          "on the same data they are the same model and add no spread",
                          stacklevel=2)
        seen.setdefault(seed, d)
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(manifest, json.dumps({
        "members": [str(d) for d in dirs], "seeds": ens.seeds, "model": ens.run.model,
        "dataset": ens.run.dataset, "joined": True, "checked_checkpoint": which}, indent=2))
    return ens


def _holds_members(folder: pathlib.Path) -> bool:
    """Whether ``folder`` holds ``member_<i>`` run directories (an ensemble trained there)."""
    return folder.is_dir() and any(p.is_dir() and _MEMBER.match(p.name)
                                   and (p / "config.json").is_file() for p in folder.iterdir())
