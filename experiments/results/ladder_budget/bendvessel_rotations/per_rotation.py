"""Each rotated copy of a rotation ensemble rolled out alone: how far one trained model is from
equivariant. For every run given, every matrix of ``fixed_rotations(R)`` (the identity first;
the copies of the ladder's ``*_rot4`` / ``*_rot8`` rungs) is evaluated as a one-member
rotation ensemble on the ladder's held-out BendVessel simulations (the model alone, last
checkpoint), with the ladder's measurement (``experiments/ladder_eval.py``). Run from the
repository root::

    python experiments/results/ladder_budget/bendvessel_rotations/per_rotation.py \
        data/bendvessel.h5 8 OUT.json RUN [RUN ...]

With ``angles`` in place of the count, the copies are turned instead by 15, 30, 60, 90, 135
and 180 degrees about each of three axes drawn uniformly on the sphere
(``numpy.random.default_rng(1)``): the error against the angle from the dataset's own
orientation. With ``angles:R``, each turned simulation is rolled out by the model as a
rotation ensemble of ``fixed_rotations(R)`` (the ``*_rot4`` rungs' copies for R = 4): member
``i`` turns the simulation by ``R_i Q``, ``Q`` the turn, so the ensemble sees the turned
simulation as it sees the dataset's own (every measure is the same in either frame).
"""

import json
import pathlib
import sys
import time

import numpy as np

sys.path.insert(0, "experiments")
from ladder_eval import evaluate_runs  # noqa: E402

from thrombojax.eval.tables import environment  # noqa: E402
from thrombojax.io.outputs import atomic_write_text  # noqa: E402
from thrombojax.simulator.rotations import fixed_rotations  # noqa: E402

ANGLES_DEG = (15, 30, 60, 90, 135, 180)


def angle_rotations() -> tuple[np.ndarray, list[dict]]:
    """The rotations by each of ``ANGLES_DEG`` about three random axes, and their labels."""
    axes = np.random.default_rng(1).standard_normal((3, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    rots, labels = [], []
    for a, axis in enumerate(axes):
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        for deg in ANGLES_DEG:
            t = np.deg2rad(deg)
            rots.append(np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k)  # Rodrigues
            labels.append({"axis": a, "angle_deg": deg})
    return np.asarray(rots, np.float32), labels


def main() -> None:
    data, out = sys.argv[1], pathlib.Path(sys.argv[3])
    runs = [pathlib.Path(r) for r in sys.argv[4:]]
    mode, copies = sys.argv[2], None
    if mode.startswith("angles"):
        rots, labels = angle_rotations()
        if ":" in mode:  # a rotation ensemble of R copies at every turn
            copies = fixed_rotations(int(mode.split(":")[1]))
            labels = [{**lab, "copies": len(copies)} for lab in labels]
    else:
        rots = fixed_rotations(int(mode))
        labels = [{"rotation": i} for i in range(len(rots))]
    n = len(rots)
    rows = []
    for run in runs:
        seed = json.loads((run / "config.json").read_text())["train"]["seed"]
        for i in range(n):
            t = time.perf_counter()
            turns = rots[i:i + 1] if copies is None else copies @ rots[i]
            res = evaluate_runs([run], data, False, which="last", rotations=turns)
            mean = res["mean"]
            rows.append({
                "seed": seed, **labels[i], "matrix": rots[i].tolist(),
                "mse_full_ratio": mean["mse_full"] / mean["mse_full_cv"],
                "mse1_phase_ratio": mean["mse1_phase"] / mean["mse1_phase_cv"],
                "final_centroid_r": mean["final_centroid_r"], "max_outside": mean["max_outside"],
                "per_simulation": {k: {"final_centroid_r": v["final_centroid_r"],
                                       "max_outside": v["max_outside"]}
                                   for k, v in res["simulations"].items()},
                "seconds": time.perf_counter() - t})
            print(f"seed {seed} {labels[i]}: MSE@full/CV {rows[-1]['mse_full_ratio']:.2f}, "
                  f"centroid {mean['final_centroid_r']:.2f} r, "
                  f"outside {100 * mean['max_outside']:.1f} %", flush=True)
    atomic_write_text(out, json.dumps({"environment": environment(), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
