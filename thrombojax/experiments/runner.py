"""``thrombojax experiment run``: every run of an experiment, resumable, sharded, then the table.

The experiment folder ``DIR`` holds ``experiment.json`` (which experiment and scale it is),
``data/`` (the cached datasets, unless ``--data-dir``), ``runs/<key>/`` (one run each,
:mod:`thrombojax.experiments.execute`) and, once every run is finished, the report
(:mod:`thrombojax.experiments.report`). Running the same command again resumes: finished runs
are skipped, a killed run continues from its checkpoint, and the report is rewritten. A folder
that holds another experiment, another scale, or files thrombojax did not write is refused
unless ``--force`` (which redoes every run; datasets are kept).
"""

from __future__ import annotations

import json
import pathlib
from collections.abc import Mapping

from thrombojax.errors import OutputError
from thrombojax.experiments.data import ensure_dataset
from thrombojax.experiments.execute import execute_run, read_result, run_folder
from thrombojax.experiments.plan import plan_runs, shard
from thrombojax.experiments.report import write_report
from thrombojax.experiments.spec import Experiment
from thrombojax.io.outputs import TEMP_TAG, atomic_write_text

__all__ = ["prepare_folder", "run_experiment"]

_MANIFEST = "experiment.json"


def prepare_folder(out: pathlib.Path, experiment: Experiment, scale: str, *,
                   force: bool) -> None:
    """Create ``out`` or check that it holds this experiment at this scale (a resume).

    Workers starting together may see each other's temporary manifest: temporaries do not
    count as someone else's files."""
    manifest = out / _MANIFEST
    if manifest.is_file():
        saved = json.loads(manifest.read_text())
        if (saved.get("experiment"), saved.get("scale")) != (experiment.name, scale) \
                and not force:
            raise OutputError(f"{out}: holds experiment '{saved.get('experiment')}' at scale "
                              f"'{saved.get('scale')}'; choose another --out, or --force")
    elif out.exists() and any(TEMP_TAG not in p.name for p in out.iterdir()) and not force:
        raise OutputError(f"{out}: exists and holds no thrombojax experiment; choose a new or "
                          "empty --out, or --force")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(manifest, json.dumps({"experiment": experiment.name, "scale": scale,
                                            "file": experiment.path}, indent=2))


def run_experiment(experiment: Experiment, scale: str, out: str | pathlib.Path, *,
                   seeds: tuple[int, ...] | None = None, worker: tuple[int, int] = (0, 1),
                   data_dir: str | pathlib.Path | None = None,
                   datasets: Mapping[str, str] | None = None, force: bool = False,
                   progress: bool = False, log=print) -> dict:
    """Run (or resume) this worker's share of an experiment; report when all runs are done.

    Args:
        experiment: the loaded experiment (``--set`` already applied). scale: its scale.
        out: the experiment folder. seeds: replace the scale's seeds.
        worker: ``(i, n)``: run every n-th run from the i-th (:func:`thrombojax.experiments.
            plan.shard`). data_dir: dataset cache (default ``out/data``). datasets: preset ->
            existing file, used instead of generating.
        force: redo every run of this worker. progress: progress bars. log: one-line messages.
    Returns:
        ``{"runs", "ran", "skipped", "finished", "report"}`` (``report`` is ``None`` while
        runs of other workers are unfinished).
    """
    out = pathlib.Path(out)
    if experiment.kind == "search":
        from thrombojax.experiments.search import run_search

        return run_search(experiment, scale, out, force=force, progress=progress, log=log,
                          data_dir=data_dir, datasets=datasets)
    runs = plan_runs(experiment, scale, seeds)
    prepare_folder(out, experiment, scale, force=force)
    data_dir = pathlib.Path(data_dir) if data_dir else out / "data"
    options = experiment.scale(scale).options
    mine = shard(runs, worker)
    ran = skipped = 0
    for i, run in enumerate(mine, 1):
        folder = run_folder(out, run)
        if not force and read_result(folder) is not None:
            execute_run(experiment.name, experiment.kind, scale, run, out, None, options)
            skipped += 1  # (execute_run checked that its settings still match)
            continue
        data = (ensure_dataset(run.dataset, data_dir, given=datasets, progress=progress)
                if run.dataset else None)
        log(f"[{i}/{len(mine)}] {run.key}")
        execute_run(experiment.name, experiment.kind, scale, run, out, data, options,
                    force=force, progress=progress)
        ran += 1
    results = [read_result(run_folder(out, r)) for r in runs]
    finished = [r for r in results if r is not None]
    report = None
    if len(finished) == len(runs):
        report = write_report(experiment, scale, finished, out)
    else:
        log(f"{len(finished)} of {len(runs)} runs finished; the table is written when all are "
            "(run the same command without --worker once every worker is done)")
    return {"runs": len(runs), "ran": ran, "skipped": skipped, "finished": len(finished),
            "report": report}
