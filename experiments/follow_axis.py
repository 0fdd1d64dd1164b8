"""Rollouts without a model that follow the vessel: how far the geometry alone carries a clot.

    python experiments/follow_axis.py --dataset data/clotentry.h5 --nodes 2048 \
        --sims clotentry_008,clotentry_009 --out experiments/results/follow_axis/clotentry

Constant velocity (CV), the baseline every error here is reported beside, carries the clot
straight on; a clot driven along a vessel turns with it. These rollouts keep the clot's speed
and turn its velocity onto the vessel's local axis ``t`` (:func:`thrombojax.graph.vessel_axis.
vessel_axis`, the wall normals within ``--axis-radius`` vessel radii) at every step, from the
last two frames alone (no model, no training):

- ``axis speed, per node``: ``v_i <- |v_i| sign(v_i . t_i) t_i`` for every clot node;
- ``axis speed, rigid``: the clot moves as one body, ``v <- |V| sign(V . T) T`` with ``V`` the
  clot's mean velocity and ``T`` the mean of the nodes' axes (signed along ``V``);
- ``axis part only``: ``v_i <- (v_i . t_i) t_i`` (the speed across the vessel dropped, so the
  clot slows in bends);
- with ``--room-fit SIMS``, two rules that set the speed from the room instead of keeping it:
  ``room speed, per node`` (``v_i <- s sign(v_i . t_i) t_i``) and ``room speed, rigid``
  (``v <- s sign(V . T) T``), where ``s = a + b * clearance`` is a straight line fitted to
  every step of the simulations SIMS (:func:`clot_speed.simulation_record`: the true clot
  centroid's speed per frame against its distance to the nearest wall node, both in vessel
  radii), the clearance measured from the rollout's own clot centroid at every step; with
  ``--room-line constant`` the line is flat (``b = 0``, ``a`` the mean speed per frame of those
  steps): the clot pushed along the vessel at the training simulations' pace.

Each is rolled out alone and with the physics guards (containment, coherence) of
:func:`thrombojax.simulator.guard_set.build_guards`, from the dataset's ``skip_frames`` to the
last frame, on the simulations named. Errors in vessel radii; ratios to CV. Writes
``table.md`` and ``follow_axis.json`` (command, device, versions, date, load).
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax import study
from thrombojax.data.augment import subsample_indices
from thrombojax.data.radius import vessel_radius
from thrombojax.eval.metrics import centroid_error, fit_vessel_wall, fraction_outside, mse_per_step
from thrombojax.eval.tables import environment, markdown_table
from thrombojax.graph.vessel_axis import axis_speed_velocity, vessel_axis
from thrombojax.io.hdf5 import open_dataset
from thrombojax.io.outputs import atomic_write_text, check_targets
from thrombojax.simulator.guard_set import build_guards
from thrombojax.types import NodeType, clot_mask

RULES = ("constant velocity", "axis speed, per node", "axis speed, rigid", "axis part only")
ROOM_RULES = ("room speed, per node", "room speed, rigid")


def next_velocity(rule: str, v: jax.Array, t: jax.Array, clot: jax.Array,
                  speed: jax.Array | None = None) -> jax.Array:
    """The velocity of the next step under ``rule`` (:data:`RULES`, :data:`ROOM_RULES`: those
    move at ``speed``, a scalar in the positions' units per frame), on clot rows only."""
    if rule == "constant velocity":
        return v
    along = jnp.sum(v * t, axis=-1, keepdims=True)
    w = clot[:, None].astype(v.dtype)
    big_v = jnp.sum(w * v, axis=0) / jnp.maximum(w.sum(), 1.0)
    if rule in ROOM_RULES and speed is None:
        raise ValueError(f"rule {rule!r} needs a speed")
    if rule == "axis part only":
        new = along * t
    elif rule == "axis speed, per node":
        new = axis_speed_velocity(v, t)
    elif rule == "room speed, per node":
        new = speed * jnp.where(along < 0, -t, t)
    elif rule in ("axis speed, rigid", "room speed, rigid"):
        signed_t = jnp.where(jnp.sum(t * big_v, axis=-1, keepdims=True) < 0, -t, t)
        big_t = jnp.sum(w * signed_t, axis=0)
        big_t = big_t / jnp.maximum(jnp.linalg.norm(big_t), 1e-12)
        size = jnp.linalg.norm(big_v) if rule == "axis speed, rigid" else speed
        new = jnp.broadcast_to(size * big_t, v.shape)
    else:
        raise ValueError(f"unknown rule {rule!r}; one of {RULES + ROOM_RULES}")
    return jnp.where(clot[:, None], new, 0.0)


def room_speed(x: jax.Array, clot: jax.Array, wall: jax.Array, line: tuple[float, float],
               radius: float) -> jax.Array:
    """``a + b * clearance`` in the positions' units per frame: ``line = (a, b)`` in vessel radii
    (speed per frame against clearance), the clearance the distance from the clot centroid of
    ``x [N, 3]`` to the nearest of the wall nodes ``wall [W, 3]``."""
    w = clot[:, None].astype(x.dtype)
    centroid = jnp.sum(w * x, axis=0) / jnp.maximum(w.sum(), 1.0)
    clearance = jnp.sqrt(jnp.min(jnp.sum((wall - centroid) ** 2, axis=-1)))
    return radius * line[0] + line[1] * clearance


def roll(rule: str, x_prev, x0, node_type, n_steps: int, axis_radius: float, guards=None,
         room=None):
    """``[n_steps, N, 3]``: the rule's rollout from ``(x_prev, x0)`` (guarded if given);
    ``room = (wall [W, 3], (a, b), radius)`` for the :data:`ROOM_RULES`."""
    mask = jnp.ones(node_type.shape[0], bool)
    clot = clot_mask(node_type, mask)

    def body(carry, _):
        prev, cur = carry
        t = vessel_axis(cur, node_type, mask, radius=axis_radius)
        speed = None if room is None else room_speed(cur, clot, room[0], room[1], room[2])
        nxt = cur + next_velocity(rule, cur - prev, t, clot, speed)
        if guards is not None:
            nxt = guards.apply(nxt)[0]
        return (cur, nxt), nxt

    return jax.lax.scan(body, (x_prev, x0), None, length=n_steps)[1]


_roll = jax.jit(roll, static_argnums=(0, 4, 5))  # one compilation per rule, length, guards


def fit_room_line(ds, sims: list[str], constant: bool = False) -> tuple[float, float]:
    """``(a, b)``: the least-squares line speed = a + b * clearance (vessel radii per frame
    against vessel radii) over every step of the rollout windows of ``sims``; ``constant``:
    ``b = 0`` and ``a`` their mean speed."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))  # experiments/
    from clot_speed import simulation_record

    skip, r = max(study.skip_frames(ds), 1), vessel_radius(ds)
    recs = [simulation_record(np.asarray(ds.positions(n)), np.asarray(ds.node_type(n)), skip, r,
                              smooth=3) for n in sims]
    x = np.concatenate([rec["clearance"] for rec in recs])
    y = np.concatenate([rec["speed"] for rec in recs])
    if constant:
        return float(np.mean(y)), 0.0
    if np.ptp(x) == 0:
        raise ValueError(f"the clearance never varies over {sims}: no line to fit")
    b, a = np.polyfit(x, y, 1)
    return float(a), float(b)


def measure(ds, name: str, n_nodes: int | None, axis_radius_r: float,
            line: tuple[float, float] | None = None) -> dict:
    """Every rule alone and guarded on one simulation: MSE@full (r^2) and its ratio to CV,
    final centroid error (r), max fraction of the clot outside."""
    full = np.asarray(ds.positions(name), np.float32)
    full_nt = np.asarray(ds.node_type(name), np.int32)
    r = vessel_radius(ds)
    skip = max(study.skip_frames(ds), 1)
    idx = subsample_indices(0, full_nt, n_nodes or len(full_nt))
    pos, nt = full[:, idx], full_nt[idx]
    clot = clot_mask(nt)
    n = pos.shape[0] - 1 - skip
    true = pos[skip + 1:]
    wall = fit_vessel_wall(full[0], full_nt, wall_cells=ds[name].wall_cells)
    guards = build_guards(full[0], full_nt, pos[skip], nt, radius=r,
                          wall_cells=ds[name].wall_cells)
    rows = {}
    room = (None if line is None else
            (jnp.asarray(full[0][full_nt == NodeType.VESSEL]), tuple(line), float(r)))
    for rule in RULES + (ROOM_RULES if line is not None else ()):
        for guarded in (False, True):
            pred = np.asarray(_roll(
                rule, jnp.asarray(pos[skip - 1]), jnp.asarray(pos[skip]), jnp.asarray(nt), n,
                axis_radius_r * r, guards if guarded else None,
                room if rule in ROOM_RULES else None))
            rows[f"{rule}{', guarded' if guarded else ''}"] = {
                "mse_full": float(mse_per_step(pred, true, clot).mean()) / r**2,
                "final_centroid_r": float(centroid_error(pred, true, clot)[-1]) / r,
                "max_outside": float(fraction_outside(wall, pred, clot).max()),
            }
    cv = rows["constant velocity"]["mse_full"]
    for row in rows.values():
        row["ratio_cv"] = row["mse_full"] / cv
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dataset", required=True, help="HDF5 dataset")
    parser.add_argument("--sims", required=True, help="simulations (comma-separated)")
    parser.add_argument("--nodes", type=int, default=None,
                        help="a fixed seeded subset of this many nodes (default: all)")
    parser.add_argument("--axis-radius", type=float, default=2.0,
                        help="width of the axis' wall-normal weights, vessel radii (default 2)")
    parser.add_argument("--room-fit", default=None,
                        help="simulations (comma-separated; not those of --sims) to fit the "
                        "room rules' speed-against-clearance line on; without it, no room rule")
    parser.add_argument("--room-line", choices=("clearance", "constant"), default="clearance",
                        help="the room rules' line: speed against clearance (default), or "
                        "constant, the mean speed of --room-fit's steps")
    parser.add_argument("--out", required=True, help="output folder (table.md, JSON)")
    parser.add_argument("--force", action="store_true", help="replace existing outputs")
    args = parser.parse_args(argv)
    if args.room_line == "constant" and not args.room_fit:
        parser.error("--room-line constant needs --room-fit (the simulations whose mean speed "
                     "it takes)")
    out = pathlib.Path(args.out)
    check_targets([out / "table.md", out / "follow_axis.json"], force=args.force)
    ds = open_dataset(args.dataset)
    line = None
    if args.room_fit:
        fit = args.room_fit.split(",")
        if set(fit) & set(args.sims.split(",")):
            parser.error("--room-fit must not name a simulation of --sims (it is scored)")
        line = fit_room_line(ds, fit, constant=args.room_line == "constant")
        print(f"room line fitted on {fit}: speed = {line[0]:.4f} + {line[1]:.4f} * clearance "
              "(r per frame, r)")
    per_sim = {name: measure(ds, name, args.nodes, args.axis_radius, line)
               for name in args.sims.split(",")}
    if args.room_line == "constant":  # the flat line's rows say what they are
        per_sim = {n: {k.replace("room speed", "training pace"): v for k, v in rows.items()}
                   for n, rows in per_sim.items()}
    labels = list(next(iter(per_sim.values())))
    mean = {k: {m: float(np.mean([s[k][m] for s in per_sim.values()]))
                for m in ("ratio_cv", "final_centroid_r")} |
            {"max_outside": float(max(s[k]["max_outside"] for s in per_sim.values()))}
            for k in labels}
    rows = [[k, f"{v['ratio_cv']:.2f}", f"{v['final_centroid_r']:.2f}",
             f"{100 * v['max_outside']:.0f} %"] for k, v in mean.items()]
    env = environment()
    text = (f"# Rollouts that follow the vessel, no model ({pathlib.Path(args.dataset).name}: "
            f"{args.sims})\n\n"
            + markdown_table(["rollout", "MSE@full / CV (mean over simulations)",
                              "final centroid error (r)", "max clot outside"], rows)
            + "\n\n" + "\n".join(f"- {k}: {v}" for k, v in env.items()) + "\n")
    out.mkdir(parents=True, exist_ok=True)
    if line is not None:
        name = "Training pace" if args.room_line == "constant" else "Room rules"
        text = text.replace("\n\n- ", f"\n\n{name}: speed = {line[0]:.4f} + {line[1]:.4f} "
                            f"* clearance (r per frame, r), fitted on {args.room_fit}.\n\n- ", 1)
    atomic_write_text(out / "follow_axis.json", json.dumps(
        {"environment": env, "simulations": per_sim, "mean": mean, "room_line": line,
         "room_fit": args.room_fit, "room_line_kind": args.room_line}, indent=1))
    atomic_write_text(out / "table.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
