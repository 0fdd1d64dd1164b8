"""Does a rollout's clot change speed where the true clot does? Reads the ``result.json`` of
ladder rungs (``experiments/ladder.py``) and, per held-out simulation, compares the rollout's
centroid speed with the truth's, both smoothed over ``--smooth`` frames (the per-frame centroid
speed jitters): their correlation, their ranges, and the error along the true track per step.
No model is run. Writes ``speed_profile.md`` (with the command and date) and
``speed_profile.png`` into ``--out`` (atomically; existing files only with ``--force``).

    python speed_profile.py --out DIR RUN_FOLDER/RUNG [RUN_FOLDER/RUNG=LABEL ...]
"""

from __future__ import annotations

import argparse
import datetime
import json
import pathlib
import sys

import numpy as np

from thrombojax.io.outputs import atomic_write_text, check_targets


def smooth(x: np.ndarray, width: int) -> np.ndarray:
    """Moving mean over ``width`` frames (valid part only)."""
    return np.convolve(x, np.ones(width) / width, mode="valid")


def profile(result: dict, width: int) -> dict[str, dict]:
    """Per simulation: correlation of the smoothed speeds, their ranges, the final error along."""
    out = {}
    for name, sim in result["simulations"].items():
        pred = smooth(np.asarray(sim["speed_per_step_r"]), width)
        true = smooth(np.asarray(sim["speed_true_per_step_r"]), width)
        out[name] = {"corr": float(np.corrcoef(pred, true)[0, 1]),
                     "pred_range": (float(pred.min()), float(pred.max())),
                     "true_range": (float(true.min()), float(true.max())),
                     "final_along_r": sim["final_along_r"],
                     "final_centroid_r": sim["final_centroid_r"],
                     "along": sim["along_per_step_r"]}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rungs", nargs="+", help="rung folders holding result.json, each "
                        "optionally FOLDER=LABEL (the label of its rows; default the folder's "
                        "name)")
    parser.add_argument("--out", required=True, help="folder for speed_profile.md and .png")
    parser.add_argument("--smooth", type=int, default=10, help="frames of the moving mean")
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    args = parser.parse_args(argv)
    if args.smooth < 1:
        parser.error("--smooth must be >= 1")
    out = pathlib.Path(args.out)
    check_targets([out / "speed_profile.md", out / "speed_profile.png"], force=args.force)
    out.mkdir(parents=True, exist_ok=True)
    rows, profiles = [], {}
    for arg in args.rungs:
        folder, _, label = arg.partition("=")
        path = pathlib.Path(folder) / "result.json"
        label = label or path.parent.name
        if not path.is_file():
            raise SystemExit(f"{path}: no result.json (run the ladder on this rung first)")
        profiles[label] = prof = profile(json.loads(path.read_text()), args.smooth)
        for name, p in prof.items():
            rows.append(f"| {label} | {name} | {p['corr']:+.2f} | "
                        f"{p['pred_range'][0]:.3f}-{p['pred_range'][1]:.3f} | "
                        f"{p['true_range'][0]:.3f}-{p['true_range'][1]:.3f} | "
                        f"{p['final_along_r']:+.2f} | {p['final_centroid_r']:.2f} |")
    import matplotlib.pyplot as plt

    from thrombojax.plotting.scene import save_atomic

    sims = sorted({s for p in profiles.values() for s in p})
    fig, axes = plt.subplots(1, len(sims), figsize=(5 * len(sims), 3.6), squeeze=False)
    for ax, sim in zip(axes[0], sims, strict=True):
        for rung, prof in profiles.items():
            if sim in prof:
                ax.plot(prof[sim]["along"], label=rung)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set(title=sim, xlabel="step", ylabel="error along the true track (r; + ahead)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_atomic(lambda tmp: fig.savefig(tmp, dpi=110), out / "speed_profile.png")
    plt.close(fig)
    text = "\n".join([
        f"# Rollout clot speed against the truth's (moving mean over {args.smooth} frames)", "",
        "| rung | simulation | corr(speed, true speed) | rollout speed range (r/frame) | "
        "true speed range | final error along the track (r; + ahead) | final centroid error (r) |",
        "|---|---|---|---|---|---|---|", *rows, "",
        f"- command: python {' '.join(sys.argv)}",
        f"- date: {datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}",
        "- no model run: read from the rungs' result.json", ""])
    atomic_write_text(out / "speed_profile.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
