"""How far BendVessel's true clot runs in its exit, per simulation: the part of a final error
that a step cannot know before the exit begins.

Every true clot slides at an almost constant speed and then, over its last frames, speeds up as
it passes the outlet's flare. The frame rate of each simulation is set so that every clot
travels the same length, so the steady speeds agree within a few per cent; how far the exit
carries the clot does not: it depends on the simulation's drive, friction and clot. Per
simulation this prints (vessel radii, from the clot centroid of the dataset's frames):

- ``steady``: the median centroid speed per frame;
- the exit's first frame: the start of the last run of frames whose speed exceeds
  ``EXIT_SPEEDUP`` times the steady speed (the threshold of
  ``../bendvessel_shapes/exit/exit_split.py``, searched from the end so that a clot that
  overshoots at its start is not taken for an exit), and the exit's number of frames;
- ``extra``: how much farther the clot runs in its exit than at its steady speed, the exit's
  own share of the displacement;
- ``length``: the clot's mean extent along its motion over the steady frames
  ``STEADY_FRAMES`` (does the steady clot show how far its exit will carry it?);
- the simulation's drive ratio, friction and flow speed (its attributes).

Then, for the simulations named in ``--held-out``: how far each one's ``extra`` lies from the
mean of the other simulations', the final error along the track of a step that knew everything
but which simulation it is in. With ``--steady F``: the share of the training windows (every
``s_{t-1}, s_t, s_{t+1}`` of the simulations neither held out nor in ``--validation``) that
``thrombojax train --speed-noise-steady F`` leaves un-noised, counted by running
:func:`thrombojax.train.noise.add_speed_noise` on each. No model is run; the table is written
atomically and replaced only with ``--force``. From the repository root::

    python experiments/results/ladder_budget/bendvessel_exit/exit_truth.py data/bendvessel.h5 \\
        --held-out bendvessel_005,bendvessel_012,bendvessel_019 --validation bendvessel_009 \\
        --steady 0.1 --out exit_truth.md
"""

from __future__ import annotations

import argparse
import datetime
import functools
import os
import pathlib
import platform
import sys

import jax
import numpy as np

from thrombojax.data.radius import vessel_radius
from thrombojax.errors import ConfigError
from thrombojax.eval.metrics import clot_centroids
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.train.noise import add_speed_noise
from thrombojax.types import clot_mask

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "bendvessel_shapes" / "exit"))
from exit_split import EXIT_SPEEDUP  # noqa: E402

STEADY_FRAMES = range(10, 30)


def exit_of(speed: np.ndarray) -> int:
    """The first frame step of the last run of steps faster than ``EXIT_SPEEDUP`` x the median
    (``len(speed)`` when the last step is not fast: no exit)."""
    fast = speed > EXIT_SPEEDUP * np.median(speed)
    k = len(speed)
    while k > 0 and fast[k - 1]:
        k -= 1
    return k


def measure(ds, name: str, radius: float) -> dict:
    """The exit's numbers of one simulation (module docstring), in vessel radii."""
    pos = ds.positions(name)
    clot = clot_mask(ds.node_type(name))
    centroid = clot_centroids(pos, clot) / radius
    speed = np.linalg.norm(np.diff(centroid, axis=0), axis=1)
    steady = float(np.median(speed))
    k = exit_of(speed)
    n_exit = len(speed) - k
    lengths = []
    for f in STEADY_FRAMES:
        u = centroid[f + 1] - centroid[f - 1]
        along = (pos[f][clot] / radius - centroid[f]) @ (u / np.linalg.norm(u))
        lengths.append(along.max() - along.min())
    attrs = ds.sim_attrs(name)
    return {"name": name, "steady": steady, "exit_from": k, "n_exit": n_exit,
            "extra": float(speed[k:].sum() - steady * n_exit), "length": float(np.mean(lengths)),
            **{key: float(attrs[key]) if key in attrs else float("nan")
               for key in ("drive_ratio", "friction", "flow_speed")}}


@functools.partial(jax.jit, static_argnames="fraction")
def _noised(windows, keys, node_type, mask, *, fraction: float):
    """Every three-frame window ``[W, 3, N, 3]`` through ``add_speed_noise(..., steady=fraction)``
    with its own key, in one call (compiled once per window and node count)."""
    return jax.vmap(lambda w, k: add_speed_noise(k, w, node_type, mask, std=0.3, current=1,
                                                 steady=fraction))(windows, keys)


def unnoised_share(ds, names: list[str], fraction: float) -> tuple[int, int]:
    """(windows ``add_speed_noise(..., steady=fraction)`` returns as given, windows) over the
    three-frame windows of ``names`` (window ``t`` drawn with ``jax.random.key(t)``)."""
    kept = total = 0
    for name in names:
        pos, nt = ds.positions(name), ds.node_type(name)
        ts = np.arange(1, len(pos) - 1)
        windows = np.stack([pos[t - 1:t + 2] for t in ts])
        keys = jax.vmap(jax.random.key)(ts)
        out = np.asarray(_noised(windows, keys, nt, np.ones(len(nt), bool), fraction=fraction))
        kept += int(sum(np.array_equal(o, w) for o, w in zip(out, windows, strict=True)))
        total += len(ts)
    return kept, total


def provenance(radius: float) -> str:
    """The table's last line: no model, the vessel radius, the command, date, versions, load."""
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    return (f"From the dataset's frames (no model run), vessel radius {radius:g}. Command: "
            f"python {' '.join(sys.argv)}; {stamp}; Python {platform.python_version()}, "
            f"jax {jax.__version__}, numpy {np.__version__}; load {os.getloadavg()[0]:.1f}.")


def write_table(out: pathlib.Path, lines: list[str], radius: float) -> None:
    """Write ``lines`` and the :func:`provenance` line to ``out`` atomically, and print them."""
    lines = [*lines, "\n" + provenance(radius)]
    atomic_write_text(out, "\n".join(lines) + "\n")
    print("\n".join(lines))


def add_split_arguments(ap: argparse.ArgumentParser) -> None:
    """The arguments :func:`open_split` reads: ``data``, ``--held-out``, ``--validation``,
    ``--out`` and ``--force``."""
    ap.add_argument("data", type=pathlib.Path, help="the BendVessel dataset (.h5)")
    ap.add_argument("--held-out", default="", help="comma-separated held-out simulations")
    ap.add_argument("--validation", default="", help="comma-separated validation simulations")
    ap.add_argument("--out", type=pathlib.Path, required=True)
    ap.add_argument("--force", action="store_true", help="replace an existing --out")


def open_split(args) -> tuple:
    """``(dataset, held-out names, validation names)`` of the parsed ``data``, ``--held-out``
    and ``--validation`` arguments, once ``--out`` may be written (``--force``); every name is
    checked to be in the dataset."""
    check_targets([args.out], force=args.force)
    ds = open_dataset(args.data)
    held = [s for s in args.held_out.split(",") if s]
    validation = [s for s in args.validation.split(",") if s]
    missing = [s for s in held + validation if s not in ds]
    if missing:
        raise ConfigError(f"{args.data}: no simulation {', '.join(missing)}")
    return ds, held, validation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_split_arguments(ap)  # --held-out: scored against the mean of the others
    ap.add_argument("--steady", type=float, default=0.0, help="also count the training "
                    "windows --speed-noise-steady F leaves un-noised, the held-out and "
                    "validation simulations left out (0: skip)")
    args = ap.parse_args()
    ds, held, validation = open_split(args)
    radius = float(vessel_radius(ds))
    rows = [measure(ds, name, radius) for name in ds.names]
    no_exit = [r["name"] for r in rows if r["n_exit"] == 0]
    if no_exit:
        raise ConfigError(f"{args.data}: no exit found in {', '.join(no_exit)} (the last step "
                          f"is not {EXIT_SPEEDUP} x the median speed)")
    lines = ["| simulation | steady speed (r/frame) | exit from frame | exit frames | extra run "
             "in the exit (r) | steady clot length along its motion (r) | drive ratio | "
             "friction | flow speed |", "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {r['name']} | {r['steady']:.3f} | {r['exit_from']} | {r['n_exit']} | "
              f"{r['extra']:.2f} | {r['length']:.2f} | {r['drive_ratio']:.2f} | "
              f"{r['friction']:.3f} | {r['flow_speed']:.3f} |" for r in rows]
    extra = np.array([r["extra"] for r in rows])
    drive = np.array([r["drive_ratio"] for r in rows])
    length = np.array([r["length"] for r in rows])
    lines.append(f"\nExtra run in the exit over all {len(rows)} simulations: mean "
                 f"{extra.mean():.2f} r, std {extra.std():.2f} r, range {extra.min():.2f}-"
                 f"{extra.max():.2f} r; "
                 f"correlation with the drive ratio {np.corrcoef(extra, drive)[0, 1]:+.2f}, with "
                 f"the steady clot's length {np.corrcoef(extra, length)[0, 1]:+.2f}; the length's "
                 f"with the drive ratio {np.corrcoef(length, drive)[0, 1]:+.2f} (frames "
                 f"{STEADY_FRAMES.start}-{STEADY_FRAMES.stop - 1}).")
    if held:
        others = np.array([r["extra"] for r in rows if r["name"] not in held])
        lines.append(f"\nAgainst the mean of the other {others.size} simulations "
                     f"({others.mean():.2f} r), the step that knows all but the simulation:")
        lines += [f"- {r['name']}: {r['extra'] - others.mean():+.2f} r"
                  for r in rows if r["name"] in held]
        gaps = np.array([r["extra"] - others.mean() for r in rows if r["name"] in held])
        lines.append(f"- mean |gap| {np.abs(gaps).mean():.2f} r")
    if args.steady > 0:
        training = [n for n in ds.names if n not in held + validation]
        kept, total = unnoised_share(ds, training, args.steady)
        lines.append(f"\n`--speed-noise-steady {args.steady:g}` leaves {kept} of the {total} "
                     f"training windows un-noised ({100 * kept / total:.1f} %; the {len(training)}"
                     f" simulations neither held out nor validation, clean frames).")
    write_table(args.out, lines, radius)


if __name__ == "__main__":
    main()
