"""``make demo``: the whole pipeline on a small BendVessel-like problem, on the CPU, in minutes.

    python experiments/demo.py --out demo_output [--tiny]      # what `make demo` runs

1. generate a small BendVessel-like dataset with the built-in solver (a few rotated copies
   of the bent tube, fewer than the study's 20);
2. train a small MeshGraphNet for a few minutes (one calibration epoch measures the speed of
   this machine, then the epoch count is chosen to fit ``train_minutes``, so the learning-rate
   schedule runs its whole course);
3. evaluate it (single-step test MSE beside the constant-velocity baseline);
4. roll it out on the test simulation (trajectory HDF5, ParaView XDMF, GIF, error plots);
5. benchmark rollouts of all three models at the BendVessel size (random-initialised study
   configs, timing only, plus the trained MeshGraphNet) against Abaqus and our solver;
6. export the test simulation's ground truth for ParaView;

and print where everything is. ``--tiny`` shrinks every stage to seconds (used by the tests).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import shutil
import sys
import time

from thrombojax.errors import ThrombojaxError
from thrombojax.eval.bench import bench, bench_markdown
from thrombojax.eval.report import rollout_run
from thrombojax.eval.single_step import evaluate_run
from thrombojax.io.export import export_file
from thrombojax.io.outputs import fresh_owned_folder
from thrombojax.sim.generate import generate_dataset
from thrombojax.sim.presets import get_preset
from thrombojax.train.loop import train
from thrombojax.train.recipes import DEFAULT_RECIPE, RECIPES, recipe

__all__ = ["DemoConfig", "run_demo", "main"]


@dataclasses.dataclass(frozen=True)
class DemoConfig:
    """Sizes of the demo stages.

    Attributes:
        preset: solver preset. n_sims: simulations generated. n_frames: frames per simulation
            (``None``: the preset's).
        train_minutes: training time budget (the epoch count is calibrated to fit it).
        min_epochs, max_epochs: bounds of the calibrated epoch count.
        model_config: MeshGraphNet overrides (small, fast on CPU).
        batch_size: training batch size. bench_steps: rollout steps timed per model (the
            rest of the 35 is extrapolated per step). tiny_models: bench the tiny configs.
        recipe: the training recipe (``thrombojax/train/recipes.py``; the default of
            ``thrombojax train``: ``outlet``, the room recipe with the outlet features).
        max_rotation: largest random rotation (radians) of training samples. 0 here: the
            BendVessel simulations are already rotated 0-190 degrees about one axis, and with
            the study's random 3-D rotations up to pi a small MeshGraphNet does not get below
            the mean predictor in a few CPU minutes (measured: loss 0.97 vs 0.59 without).
    """

    preset: str = "bendvessel"
    n_sims: int = 6
    n_frames: int | None = None
    train_minutes: float = 6.0
    min_epochs: int = 2
    max_epochs: int = 60
    model_config: dict = dataclasses.field(
        default_factory=lambda: {"hidden": 32, "processor_size": 5, "max_neighbors": 12})
    batch_size: int = 4
    bench_steps: int = 5
    tiny_models: bool = False
    recipe: str = DEFAULT_RECIPE
    max_rotation: float = 0.0

    @classmethod
    def tiny(cls) -> DemoConfig:
        return cls(preset="bendvessel-tiny", n_sims=4, train_minutes=0.0, model_config={},
                   batch_size=2, bench_steps=2, tiny_models=True)


def _stage(title: str) -> float:
    print(f"\n== {title}", flush=True)
    return time.perf_counter()


def run_demo(out: str | pathlib.Path, config: DemoConfig = DemoConfig(), *,
             progress: bool = True) -> dict[str, pathlib.Path]:
    """Run the demo into ``out``; returns label -> path of what it wrote.

    Args:
        out: output folder (created; an earlier demo's files are replaced).
        config: stage sizes (:meth:`DemoConfig.tiny` for a seconds-long run).
        progress: progress bars.
    Returns:
        Paths of the dataset, run, tables, plots, animation and exports.
    """
    out = fresh_owned_folder(out, "demo")  # never removes a folder the demo did not make
    start = time.perf_counter()
    paths: dict[str, pathlib.Path] = {}

    t = _stage(f"1/6 generate {config.n_sims} '{config.preset}' simulations (built-in solver)")
    preset = get_preset(config.preset)
    if config.n_frames is not None:
        preset = dataclasses.replace(preset, n_frames=config.n_frames)
    data = generate_dataset(preset, out / "data" / f"{config.preset}.h5", n_sims=config.n_sims,
                            seed=0, plot=True, progress=progress)
    paths["dataset"] = pathlib.Path(data)
    paths["dataset_png"] = pathlib.Path(data).with_suffix(".png")
    print(f"   {time.perf_counter() - t:.0f} s")

    t = _stage(f"2/6 train a small MeshGraphNet (~{config.train_minutes:g} min)")
    common = {**recipe(config.recipe), "tiny": config.tiny_models,
              "model_config": dict(config.model_config), "batch_size": config.batch_size,
              "n_val": 1, "n_test": 1, "max_rotation": config.max_rotation}
    epochs = _calibrate_epochs(data, out / "calibration", config, common, progress)
    print(f"   calibrated: {epochs} epochs fit the budget")
    run = out / "run_mgn"
    train(data, "mgn", run, epochs=epochs, warmup_epochs=min(2.0, epochs / 5),
          progress=progress, **common)
    paths["run"] = run
    paths["loss_png"] = run / "loss.png"
    print(f"   {time.perf_counter() - t:.0f} s")

    t = _stage("3/6 evaluate: single-step test MSE")
    ev = evaluate_run(run, data, out_dir=out / "evaluate", progress=progress)
    print(ev["table"], end="")
    paths["evaluate"] = out / "evaluate" / "evaluate.md"

    _stage("4/6 roll out on the test simulation")
    ro = rollout_run(run, data, out / "rollout", split="test")
    print(ro["table"], end="")
    verdicts = [rollout_verdict(name, rep["summary"], ro["model"])
                for name, rep in ro["simulations"].items()]
    for name, rep in ro["simulations"].items():
        for key in ("gif", "summary_png", "error_png", "metrics_png", "prediction",
                    "trajectory"):
            paths[f"rollout_{key}"] = pathlib.Path(rep["files"][key])
        paths["rollout_table"] = out / "rollout" / "rollout.md"
        test_name = name
    print(f"   {time.perf_counter() - t:.0f} s")

    t = _stage("5/6 benchmark rollouts (BendVessel size)")
    rand = bench(("mgn", "transolver", "erwin"), ("bendvessel",), tiny=config.tiny_models,
                 max_steps=config.bench_steps, repeats=2, dataset=str(data),
                 solver_datasets=(str(data),), progress=progress)
    trained = bench(("mgn",), ("bendvessel",), runs={"mgn": str(run)},
                    max_steps=config.bench_steps, repeats=2, dataset=str(data),
                    solver_datasets=(str(data),), progress=progress)
    rand["results"] += trained["results"]
    _write_bench(rand, out / "bench")
    print((out / "bench" / "bench.md").read_text().split("\n\n")[1])
    paths["bench"] = out / "bench" / "bench.md"
    print(f"   {time.perf_counter() - t:.0f} s")

    _stage("6/6 export the test simulation's ground truth for ParaView")
    paths["export"] = export_file(data, out / "export", names=[test_name])[0]

    print("\n== in plain words")
    for line in verdicts:
        print(f"   {line}")
    print(f"\n== done in {time.perf_counter() - start:.0f} s. Open:")
    width = max(map(len, paths))
    for key, path in paths.items():
        print(f"   {key:<{width}}  {path}")
    return paths


def rollout_verdict(name: str, summary: dict, model: str) -> str:
    """One sentence: the rollout against constant velocity (CV), in vessel radii (r)."""
    m, cv = summary[model], summary["constant velocity"]
    ratio = m["ratio_to_cv"]["mse@full"]
    word = "better than" if ratio < 1 else "worse than"
    return (f"{name}: over the whole rollout the {model} surrogate's error is {ratio:.2f}x that "
            f"of constant velocity ({word} extrapolating the current velocity); its clot "
            f"centroid ends {m['final_centroid_error_r']:.2f} r from the truth (CV: "
            f"{cv['final_centroid_error_r']:.2f} r); at most {100 * m['max_fraction_outside']:.0f}"
            f" % of its clot is outside the vessel (CV: {100 * cv['max_fraction_outside']:.0f}"
            " %).")


def _calibrate_epochs(data, folder: pathlib.Path, config: DemoConfig, common: dict,
                     progress: bool) -> int:
    """Train one epoch to time this machine; return the epochs that fit the budget."""
    if config.train_minutes <= 0:
        return config.min_epochs
    stamps: list[float] = []
    train(data, "mgn", folder, epochs=1, warmup_epochs=0.0, progress=progress,
          callback=lambda step, metrics: stamps.append(time.perf_counter()), **common)
    shutil.rmtree(folder)
    steps = len(stamps)
    # the first step includes compilation: time the others, extrapolate to a whole epoch
    per_step = (stamps[-1] - stamps[0]) / max(steps - 1, 1)
    epoch_s = per_step * steps
    fit = int(config.train_minutes * 60 // max(epoch_s, 1e-9))
    return int(min(max(fit, config.min_epochs), config.max_epochs))


def _write_bench(result: dict, folder: pathlib.Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    result.pop("table", None)
    (folder / "bench.json").write_text(json.dumps(result, indent=2))
    (folder / "bench.md").write_text(bench_markdown(result))


def main(argv: list[str] | None = None) -> int:
    """Command-line entry: ``python experiments/demo.py --out DIR [--tiny]``."""
    parser = argparse.ArgumentParser(prog="python experiments/demo.py", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="demo_output", help="output folder (replaced)")
    parser.add_argument("--tiny", action="store_true", help="seconds-long version (tests)")
    parser.add_argument("--train-minutes", type=float, help="training time budget (minutes)")
    parser.add_argument("--recipe", choices=sorted(RECIPES), default=None,
                        help=f"training recipe (default: {DEFAULT_RECIPE}, the default of "
                             "`thrombojax train`; thrombojax/train/recipes.py)")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    args = parser.parse_args(argv)
    config = DemoConfig.tiny() if args.tiny else DemoConfig()
    if args.train_minutes is not None:
        config = dataclasses.replace(config, train_minutes=args.train_minutes)
    if args.recipe is not None:
        config = dataclasses.replace(config, recipe=args.recipe)
    try:
        run_demo(args.out, config, progress=not args.quiet)
    except ThrombojaxError as err:
        print(f"demo: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
