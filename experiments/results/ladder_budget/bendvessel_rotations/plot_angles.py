"""Plot ``per_rotation.py``'s results against the angle from the dataset's own orientation:
the final centroid error (r), the largest share of the clot outside the vessel and the full
rollout's MSE against constant velocity, the mean over the three axes with their range, per
model (angle 0: the identity row of the same model's ``fixed_rotations`` run, or a ladder
rung's ``result.json``, e.g. the ``*_rot4`` rung for an ``angles:4`` run). Writes the plot
and a markdown table. Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_rotations/plot_angles.py OUT_STEM \
        LABEL ANGLES.json ROTATIONS_OR_RESULT.json [LABEL ANGLES.json ...]
"""

import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

KEYS = (("final_centroid_r", "final centroid error (r)", 1.0),
        ("max_outside", "max clot outside (%)", 100.0),
        ("mse_full_ratio", "MSE@full / constant velocity", 1.0))


def curves(angles_json: str, rotations_json: str) -> dict:
    """``{key: (angles, mean, lo, hi)}`` over the axes; angle 0 from the identity row."""
    rows = json.loads(pathlib.Path(angles_json).read_text())["rows"]
    zero = json.loads(pathlib.Path(rotations_json).read_text())
    if "rows" in zero:
        ident = next(r for r in zero["rows"] if r.get("rotation") == 0)
    else:  # a ladder rung's result.json
        mean = zero["mean"]
        ident = {"final_centroid_r": mean["final_centroid_r"],
                 "max_outside": mean["max_outside"],
                 "mse_full_ratio": mean["mse_full"] / mean["mse_full_cv"]}
    angles = sorted({r["angle_deg"] for r in rows})
    out = {}
    for key, _, scale in KEYS:
        vals = [[ident[key] * scale]] + [[r[key] * scale for r in rows if r["angle_deg"] == a]
                                         for a in angles]
        out[key] = ([0, *angles], [float(np.mean(v)) for v in vals],
                    [float(np.min(v)) for v in vals], [float(np.max(v)) for v in vals])
    return out


def main() -> None:
    stem, args = pathlib.Path(sys.argv[1]), sys.argv[2:]
    models = {args[i]: curves(args[i + 1], args[i + 2]) for i in range(0, len(args), 3)}
    fig, axes = plt.subplots(1, len(KEYS), figsize=(5 * len(KEYS), 4))
    for ax, (key, title, _) in zip(axes, KEYS, strict=True):
        for label, c in models.items():
            x, mean, lo, hi = c[key]
            ax.plot(x, mean, marker="o", label=label)
            ax.fill_between(x, lo, hi, alpha=0.15)
        ax.set_xlabel("rotation from the dataset's orientation (degrees)")
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Held-out BendVessel turned by a rotation, the model alone (mean of 3 axes, "
                 "range shaded)", fontsize=10)
    fig.tight_layout()
    fig.savefig(stem.with_suffix(".png"), dpi=110)
    lines = ["| model | " + " | ".join(f"{a} deg" for a in next(iter(models.values()))[
        KEYS[0][0]][0]) + " |"]
    lines.append("|---" * (1 + len(next(iter(models.values()))[KEYS[0][0]][0])) + "|")
    for key, title, _ in KEYS:
        for label, c in models.items():
            lines.append(f"| {label}: {title} | " + " | ".join(
                f"{m:.2f} ({lo:.2f}-{hi:.2f})" for m, lo, hi in zip(*c[key][1:], strict=True))
                + " |")
    stem.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
