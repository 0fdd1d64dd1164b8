"""Where the true clot's speed comes from, and what rules of speed alone give over a rollout.

    python experiments/clot_speed.py --dataset data/clotentry.h5 \
        --out experiments/results/clot_speed/clotentry

No model. For every simulation, the true clot centroid's speed per frame (vessel radii r per
frame) over the rollout window (frames from the dataset's ``skip_frames`` to the last), beside
two quantities of the geometry at the centroid: the *clearance* (distance from the centroid to
the nearest wall node, r) and the *curvature* of the centroid's own track (turning angle per r
of travel, smoothed over ``--smooth`` frames). Then the final error along the track of two
rules that move the clot along its true path and only choose its speed:

- **start speed**: the speed of the frame the rollout starts from, kept for every step (what a
  step that carries its input speed over does, e.g. the vessel-following prior alone);
- **others' mean speed**: the mean speed per frame over the rollout windows of the *other*
  simulations (leave one out), for every step;
- **clearance fit**: a speed from the clearance where the rule's clot stands on the true track,
  by a straight line fitted to the other simulations' (clearance, speed) pairs of every step
  (leave one out); the best a step can do that sets its speed from the local room alone;
- **physical parameters**: the clot's speed in the solver's time units (mean speed per frame
  over the simulation attribute ``dt``) from the simulation's own inputs
  (:data:`PARAMETERS`, the attributes the generator draws per simulation), by a ridge fit on
  the other simulations (standardised inputs, log speed; each ridge weight of :data:`RIDGE`
  tried, the one with the smallest largest error reported: an optimistic choice), times its
  ``dt``, for every step; what a step that knew the material, the load and the frame's length
  could say about its speed per frame;
- **exit timing**: the true track's distance from the start to the vessel's far end (the
  *exit*: where the centroid passes the wall node furthest along the clot's last direction of
  travel) over the number of steps the *other* simulations' clots take to reach theirs, for
  every step. It uses a convention of the data, not physics: each run ends when its clot has
  left the vessel and is resampled to a fixed number of frames, so every clot reaches the
  exit at about the same frame, and the speed per frame follows from the distance left.

The error along the track is ``|rule's travel - true travel|``: the distance between the true
final centroid and where the rule's clot stands on the true track. It is a lower bound of a
rollout's final centroid error for the same speed, since a rollout may also leave the track.
Writes ``table.md``, ``clot_speed.json`` (per simulation and per frame) and ``speed.png``, with
the command, device, versions and date.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import numpy as np

from thrombojax import study
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import clot_centroids
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.types import NodeType, clot_mask

PARAMETERS = ("friction", "drive_ratio", "flow_speed", "young", "poisson", "oversize",
              "damping_alpha")
"""Simulation attributes the physical-parameters rule reads (the generator's per-simulation
draws); those missing from any simulation, or equal in all, are left out."""
RIDGE = (0.1, 1.0, 10.0, 100.0)
"""Ridge weights the physical-parameters rule tries (on standardised inputs)."""
EXIT_TAIL = 10
"""Frames at the end of the window whose centroid displacement gives the last direction."""


def centroid_speed(positions: np.ndarray, clot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clot centroids ``[T, 3]`` (:func:`thrombojax.eval.metrics.clot_centroids`) and the speed
    per frame ``[T - 1]`` (|c_{t+1} - c_t|) of one simulation ``positions [T, N, 3]``."""
    c = clot_centroids(positions, clot)
    return c, np.linalg.norm(np.diff(c, axis=0), axis=-1)


def track_curvature(centroids: np.ndarray, smooth: int) -> np.ndarray:
    """Turning angle per unit of travel of the centroid track at each frame ``[T]`` (0 at the
    ends), from displacements summed over ``smooth`` frames on each side."""
    out = np.zeros(len(centroids))
    if len(centroids) <= 2 * smooth:
        return out
    a = centroids[smooth:-smooth] - centroids[:-2 * smooth]
    b = centroids[2 * smooth:] - centroids[smooth:-smooth]
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    ok = (na > 0) & (nb > 0)
    cos = np.clip((a * b).sum(-1) / np.where(ok, na * nb, 1.0), -1.0, 1.0)
    out[smooth:-smooth] = np.where(ok, np.arccos(cos) / np.where(ok, 0.5 * (na + nb), 1.0), 0.0)
    return out


def clearance(centroids: np.ndarray, wall: np.ndarray) -> np.ndarray:
    """Distance from each centroid ``[T, 3]`` to the nearest of the wall nodes ``[W, 3]``."""
    return np.array([np.sqrt(((wall - c) ** 2).sum(-1).min()) for c in centroids])


def exit_crossing(centroids: np.ndarray, wall: np.ndarray) -> tuple[float, float] | None:
    """Where the centroid track ``[S + 1, 3]`` (the start frame, then one centroid per step)
    passes the vessel's far end: ``(steps, distance)``, the fractional number of steps from
    the start and the track's arc length there, or None if it never does. The far end is the
    plane, across the clot's last direction of travel (over :data:`EXIT_TAIL` frames), through
    the wall node furthest along it."""
    tail = min(EXIT_TAIL, len(centroids) - 1)
    direction = centroids[-1] - centroids[-1 - tail]
    if tail < 1 or not np.linalg.norm(direction) > 0:
        return None
    direction = direction / np.linalg.norm(direction)
    plane, along = float((wall @ direction).max()), centroids @ direction
    past = np.flatnonzero(along >= plane)
    if not len(past) or past[0] == 0:
        return None
    k = int(past[0])
    frac = (plane - along[k - 1]) / (along[k] - along[k - 1])
    seg = np.linalg.norm(np.diff(centroids[:k + 1], axis=0), axis=-1)
    return float(k - 1 + frac), float(seg[:-1].sum() + frac * seg[-1])


def simulation_record(positions: np.ndarray, node_type: np.ndarray, skip: int, r: float,
                      smooth: int) -> dict:
    """The per-frame speed, clearance and curvature of one simulation over its rollout window
    (frames ``skip - 1 .. T - 1``: the first entry is the speed the rollout starts with), in r."""
    if positions.shape[0] < skip + 2:
        raise ValueError(f"{positions.shape[0]} frames leave no rollout window after "
                         f"skip_frames {skip}")
    clot = clot_mask(node_type)
    wall = positions[0][node_type == NodeType.VESSEL].astype(np.float64)
    if not len(wall):
        raise ValueError("no vessel (wall) node: clearance needs the wall")
    c, speed = centroid_speed(positions, clot)
    window = speed[skip - 1:] / r  # [steps + 1]: entry 0 is x_skip - x_{skip-1}
    cur = track_curvature(c, smooth)[skip:] * r  # at the frames the steps start from
    clear = clearance(c[skip:-1], wall) / r
    crossing = exit_crossing(c[skip:].astype(np.float64), wall)
    return {"start_speed": float(window[0]), "speed": window[1:].tolist(),
            "clearance": clear.tolist(), "curvature": cur[:-1].tolist(),
            "travel": float(window[1:].sum()), "steps": int(len(window) - 1),
            "exit_steps": None if crossing is None else crossing[0],
            "exit_distance": None if crossing is None else crossing[1] / r}


def clearance_rule(sim: dict, others: list[dict]) -> float:
    """Signed final error along the track (r; + ahead) of the clearance-fit rule on ``sim``:
    a line ``speed = a + b * clearance`` fitted to every step of ``others``, applied in a closed
    loop (each step's clearance read, by interpolation over arc length, where the rule's clot
    stands on ``sim``'s true track). NaN when the others' clearances do not vary."""
    x = np.concatenate([np.asarray(o["clearance"]) for o in others]) if others else np.zeros(0)
    if len(x) < 2 or np.ptp(x) == 0:
        return float("nan")
    y = np.concatenate([np.asarray(o["speed"]) for o in others])
    slope, intercept = np.polyfit(x, y, 1)
    speed, clear = np.asarray(sim["speed"]), np.asarray(sim["clearance"])
    arc = np.concatenate([[0.0], np.cumsum(speed)[:-1]])  # the true clot's travel at each step
    travel = 0.0
    for _ in range(len(speed)):
        travel += intercept + slope * float(np.interp(travel, arc, clear))
    return float(travel - sim["travel"])


def exit_rule(sim: dict, others: list[dict]) -> float:
    """Signed final error along the track (r; + ahead) of the exit-timing rule on ``sim``: its
    distance to the exit over the others' mean number of steps to theirs, every step. NaN
    where a clot never reaches its exit."""
    steps = [o.get("exit_steps") for o in others]
    if sim.get("exit_distance") is None or not steps or None in steps:
        return float("nan")
    return float(sim["exit_distance"] / np.mean(steps) * sim["steps"] - sim["travel"])


def parameter_rule(sims: dict[str, dict]) -> dict:
    """Signed final errors along the track (r; + ahead) of the physical-parameters rule, leave
    one out: ``{"lambda", "inputs", "errors": {name: error}, "largest_by_lambda"}``, at the
    ridge weight of :data:`RIDGE` whose largest error is smallest; NaN errors where a
    simulation lacks ``dt`` or fewer than three simulations carry every input."""
    names = list(sims)
    inputs = [k for k in PARAMETERS
              if all(k in s.get("parameters", {}) for s in sims.values())
              and np.ptp([s["parameters"][k] for s in sims.values()]) > 0]
    if not inputs or len(names) < 3 or any(not s.get("dt") for s in sims.values()):
        return {"lambda": None, "inputs": inputs, "errors": {n: float("nan") for n in names},
                "largest_by_lambda": {}}
    x = np.array([[sims[n]["parameters"][k] for k in inputs] for n in names])
    dt = np.array([sims[n]["dt"] for n in names])
    mean = np.array([sims[n]["travel"] / sims[n]["steps"] for n in names])
    y = np.log(mean / dt)  # log speed in the solver's time units
    by_lambda = {}
    for lam in RIDGE:
        errors = {}
        for i, name in enumerate(names):
            keep = np.arange(len(names)) != i
            mu, sd = x[keep].mean(0), x[keep].std(0)
            sd = np.where(sd > 0, sd, 1.0)
            z, y0 = (x[keep] - mu) / sd, y[keep].mean()
            w = np.linalg.solve(z.T @ z + lam * np.eye(len(inputs)), z.T @ (y[keep] - y0))
            speed = np.exp(y0 + ((x[i] - mu) / sd) @ w) * dt[i]
            errors[name] = float((speed - mean[i]) * sims[name]["steps"])
        by_lambda[lam] = errors
    largest = {lam: max(abs(e) for e in errors.values()) for lam, errors in by_lambda.items()}
    best = min(largest, key=largest.get)
    return {"lambda": best, "inputs": inputs, "errors": by_lambda[best],
            "largest_by_lambda": largest}


def _corr(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.corrcoef(x, y)[0, 1]) if np.std(x) > 0 and np.std(y) > 0 else float("nan")


def summarise(sims: dict[str, dict]) -> tuple[list[list], dict]:
    """Rows of the table (one per simulation) and the pooled correlations."""
    rows = []
    params = parameter_rule(sims)
    for name, s in sims.items():
        others = [v for k, v in sims.items() if k != name]
        mean_others = (np.mean([o["travel"] / o["steps"] for o in others]) if others
                       else float("nan"))
        speed = np.asarray(s["speed"])
        rows.append([
            name, s["steps"], s["travel"], s["start_speed"], float(speed.mean()),
            float(speed.min()), float(speed.max()),
            abs(s["start_speed"] * s["steps"] - s["travel"]),
            abs(mean_others * s["steps"] - s["travel"]),
            abs(clearance_rule(s, others)),
            abs(params["errors"][name]),
            float("nan") if s.get("exit_steps") is None else s["exit_steps"],
            abs(exit_rule(s, others)),
            _corr(speed, np.asarray(s["clearance"])),
            _corr(speed, np.asarray(s["curvature"])),
        ])
    pooled = {
        "speed_vs_clearance": _corr(np.concatenate([s["speed"] for s in sims.values()]),
                                    np.concatenate([s["clearance"] for s in sims.values()])),
        "speed_vs_curvature": _corr(np.concatenate([s["speed"] for s in sims.values()]),
                                    np.concatenate([s["curvature"] for s in sims.values()])),
        "mean_speed_spread": float(np.std([s["travel"] / s["steps"] for s in sims.values()])),
        "mean_speed_mean": float(np.mean([s["travel"] / s["steps"] for s in sims.values()])),
        "mean_speed_vs_exit_distance": _corr(
            np.array([s["travel"] / s["steps"] for s in sims.values()]),
            np.array([np.nan if s.get("exit_distance") is None else s["exit_distance"]
                      for s in sims.values()])),
        "parameter_rule": {k: v for k, v in params.items() if k != "errors"},
    }
    return rows, pooled


def plot(sims: dict[str, dict], path: pathlib.Path) -> None:
    """Speed per step of every simulation, and speed against clearance (pooled)."""
    import matplotlib.pyplot as plt

    from thrombojax.plotting.scene import save_atomic

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    for name, s in sims.items():
        ax0.plot(np.arange(1, s["steps"] + 1), s["speed"], lw=0.8, label=name)
        ax1.scatter(s["clearance"], s["speed"], s=3)
    ax0.set(xlabel="rollout step", ylabel="true clot speed (r per frame)",
            title="true clot centroid speed over the rollout window")
    ax0.legend(fontsize=6, ncol=2)
    ax1.set(xlabel="clearance: centroid to nearest wall node (r)",
            ylabel="speed (r per frame)", title="speed against clearance, every step")
    fig.tight_layout()
    save_atomic(lambda tmp: fig.savefig(tmp, dpi=120), path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", required=True, help="HDF5 dataset")
    parser.add_argument("--out", required=True, help="output folder (table.md, JSON, PNG)")
    parser.add_argument("--smooth", type=int, default=3,
                        help="frames on each side for the track's curvature (default 3)")
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    args = parser.parse_args(argv)
    if args.smooth < 1:
        parser.error("--smooth must be >= 1")
    out = pathlib.Path(args.out)
    targets = [out / "table.md", out / "clot_speed.json", out / "speed.png"]
    check_targets(targets, force=args.force)
    ds = open_dataset(args.dataset)
    skip, r = max(study.skip_frames(ds), 1), vessel_radius(ds)
    sims = {}
    for name in ds.names:
        try:
            sims[name] = simulation_record(np.asarray(ds.positions(name)),
                                           np.asarray(ds.node_type(name)), skip, r, args.smooth)
        except ValueError as err:
            raise SystemExit(f"{args.dataset}: simulation {name!r}: {err}") from None
        attrs = ds.sim_attrs(name)
        sims[name]["parameters"] = {k: float(attrs[k]) for k in PARAMETERS if k in attrs}
        sims[name]["dt"] = float(attrs["dt"]) if "dt" in attrs else None
    rows, pooled = summarise(sims)
    rule = pooled["parameter_rule"]
    table = markdown_table(
        ["simulation", "steps", "true travel (r)", "start speed (r/frame)",
         "mean speed", "min speed", "max speed", "start speed kept: error along (r)",
         "others' mean speed: error along (r)", "clearance fit: error along (r)",
         "physical parameters: error along (r)", "steps to the exit",
         "exit timing: error along (r)", "corr(speed, clearance)",
         "corr(speed, curvature)"], rows)
    env = environment()
    out.mkdir(parents=True, exist_ok=True)
    plot(sims, out / "speed.png")
    atomic_write_text(out / "table.md", (
        f"# The true clot's speed over the rollout window ({pathlib.Path(args.dataset).name}, "
        f"{len(sims)} simulations, frames {skip}..end)\n\n{table}\n"
        f"Pooled over every step of every simulation: corr(speed, clearance) "
        f"{pooled['speed_vs_clearance']:.3f}, corr(speed, curvature) "
        f"{pooled['speed_vs_curvature']:.3f}; mean speed per simulation "
        f"{pooled['mean_speed_mean']:.4f} +- {pooled['mean_speed_spread']:.4f} r per frame; "
        f"across the simulations, corr(mean speed, distance to the exit) "
        f"{pooled['mean_speed_vs_exit_distance']:.3f}.\n"
        f"Physical parameters: inputs {', '.join(rule['inputs']) or 'none'}; ridge weight "
        f"{rule['lambda']} (largest error per weight: "
        + ", ".join(f"{k:g}: {v:.2f} r" for k, v in rule["largest_by_lambda"].items())
        + ").\n"
        f"One vessel radius r is {r:.4g} in the dataset's units "
        f"('{ds.attrs.get('units', '?')}').\n\n"
        + "".join(f"- {k}: {v}\n" for k, v in env.items())))
    atomic_write_text(out / "clot_speed.json", json.dumps(
        {"environment": env, "skip_frames": skip, "radius": r, "smooth": args.smooth,
         "pooled": pooled, "simulations": sims}, indent=1))
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
