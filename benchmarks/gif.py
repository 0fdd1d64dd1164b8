"""Time the rollout GIF: thrombojax's writer against matplotlib's FuncAnimation + PillowWriter.

:func:`thrombojax.eval.plots.animate_rollout` draws the figure's static parts (axes, ticks,
wall, legend, colour bars) once and per frame only the clot scatters and the titles
(:mod:`thrombojax.plotting.gif`); matplotlib's ``Animation.save`` redraws everything per frame.
Both are timed here on the same synthetic scene, alternating, and the two GIFs are compared
byte for byte.

The scene: ``--clot`` clot nodes and ``--wall`` wall nodes (the figure draws at most 1,500 of
them) in a unit cloud, the truth drifting by 0.01 per frame, the prediction the truth plus
noise; ``--frames`` frames (a ClotEntry rollout has 160 steps, 161 frames).

Usage::

    python benchmarks/gif.py [--frames 41] [--clot 2048] [--wall 6000] [--rounds 3]
        [--out FILE.md]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402

from thrombojax.eval.plots import animate_rollout, rollout_figure  # noqa: E402
from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import refuse_targets  # noqa: E402
from thrombojax.types import NodeType  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from cpu_options import finish_report, report_header  # noqa: E402  (not a package)

__all__ = ["scene", "matplotlib_gif", "main"]


def scene(frames: int, clot: int, wall: int, seed: int = 0):
    """``(pred, true, node_type)`` of the synthetic rollout."""
    rng = np.random.default_rng(seed)
    node_type = np.array([NodeType.CLOT] * clot + [NodeType.VESSEL] * wall)
    base = rng.normal(size=(clot + wall, 3))
    true = np.stack([base + 0.01 * t for t in range(frames)])
    return true + rng.normal(scale=0.01, size=true.shape), true, node_type


def matplotlib_gif(pred, true, node_type, path: Path, fps: int = 8) -> Path:
    """The same figure written by matplotlib's ``FuncAnimation.save`` with ``PillowWriter``."""
    fig, update, n = rollout_figure(pred, true, node_type)
    try:
        FuncAnimation(fig, update, frames=n).save(path, writer=PillowWriter(fps=fps))
    finally:
        plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=41)
    parser.add_argument("--clot", type=int, default=2048)
    parser.add_argument("--wall", type=int, default=6000)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", help="write the report (markdown) here")
    parser.add_argument("--force", action="store_true", help="replace an existing --out")
    args = parser.parse_args(argv)
    refuse_targets(parser, (args.out,), force=args.force, what="report")
    env = {**environment(), "matplotlib": matplotlib.__version__}
    pred, true, node_type = scene(args.frames, args.clot, args.wall)
    times: dict[str, list[float]] = {"thrombojax": [], "matplotlib": []}
    writers = {"thrombojax": lambda p: animate_rollout(pred, true, node_type, p),
               "matplotlib": lambda p: matplotlib_gif(pred, true, node_type, p)}
    same = True
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            order = list(writers) if r % 2 == 0 else list(writers)[::-1]
            for name in order:
                start = time.perf_counter()
                writers[name](Path(tmp) / f"{name}.gif")
                times[name].append(time.perf_counter() - start)
            ours, theirs = (Path(tmp) / f"{n}.gif" for n in writers)
            same &= ours.read_bytes() == theirs.read_bytes()
    med = {k: statistics.median(v) for k, v in times.items()}
    out = [*report_header("benchmarks/gif.py", env), "",
           f"{args.frames} frames, {args.clot} clot + {args.wall} wall nodes, {args.rounds} "
           "rounds alternating; seconds per GIF, median (range):", "",
           "| writer | s per GIF | ms per frame |", "|---|---|---|"]
    for name, ts in times.items():
        out.append(f"| {name} | {med[name]:.2f} ({min(ts):.2f}-{max(ts):.2f}) | "
                   f"{1e3 * med[name] / args.frames:.0f} |")
    out += ["", f"matplotlib / thrombojax: {med['matplotlib'] / med['thrombojax']:.1f}x; "
            f"the GIFs are byte-identical: {same}"]
    print("\n".join(out))
    finish_report(out, args.out)
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
