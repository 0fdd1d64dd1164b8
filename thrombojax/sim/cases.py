"""Turn a preset and a seed into concrete cases: vessel, clot mesh, drawn parameters.

Per simulation ``index`` the generator ``np.random.default_rng([seed, index])`` draws, in
this order: clot start, roll, oversize, friction, drive ratio, flow speed, Young's modulus,
Poisson's ratio; a tortuous vessel, and a bend whose shape is drawn per simulation
(``Preset.leg_out_range`` and its siblings), use their own stream ``[seed, index, 1]``. So a
simulation is reproducible on its own, whatever else is generated with it.

Contact and drive are sized from a closed-form estimate of the wall pressure of the placed
clot: an incompressible Neo-Hookean cylinder with radial stretch ``1/oversize`` and axial
stretch ``oversize^2`` and free ends presses on the wall with ``p = mu (oversize^4 -
oversize^-2)``. The penalty stiffness per unit area is ``max(p, min_contact_pressure E) /
(penetration_target r)`` (the floor covers the extra pressure in bends); the
friction that holds the clot, per unit mass, is ``g_hold = 2 friction p / r`` (lateral area over
volume of a cylinder). The final drive is ``max(drive_ratio * g_hold, min_alpha * flow_speed)``
and the mass damping ``alpha = drive / flow_speed``, so a clot that slides free moves at
``flow_speed``: the drive and the damping together act as the drag of an aspiration flow.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.sim import clot as clotmesh
from thrombojax.sim import geometry as geo
from thrombojax.sim.material import lame, reference_data
from thrombojax.sim.presets import Preset
from thrombojax.sim.solver import CaseParams, stable_dt

__all__ = ["Case", "build_vessel", "build_case", "stack_cases"]


@dataclasses.dataclass(frozen=True)
class Case:
    """One simulation before it runs (host data).

    Attributes:
        index: simulation index; params: the solver's :class:`CaseParams` (jax arrays).
        centreline: the vessel (numpy arrays; unrotated); tets: ``[C, 4]`` int32 clot tets.
        wall_points: ``[W, 3]``; wall_cells ``[F, 3]`` (indices into the wall points).
        rotation: ``[3, 3]`` applied to every output position; attrs: drawn parameters.
    """

    index: int
    params: CaseParams
    centreline: geo.Centreline
    tets: np.ndarray
    wall_points: np.ndarray
    wall_cells: np.ndarray
    rotation: np.ndarray
    attrs: dict


def build_vessel(preset: Preset, index: int, seed: int) -> tuple[geo.Centreline, dict]:
    """The (unrotated) vessel centreline of simulation ``index`` and its geometry attributes.

    The last ``outlet_flare_length`` of every vessel widens smoothly (quadratically) by
    ``outlet_flare`` times its radius, like an artery opening into a larger lumen. Without it,
    the part of the clot that has left bulges out to its rest radius, and a bulging node that
    slips back across the outlet plane would land deep inside the wall.
    """
    if preset.kind == "bend":
        shape = _bend_shape(preset, index, seed)
        pts = geo.bent_tube_points(preset.leg_in, shape["leg_out"], shape["bend_radius"],
                                   shape["bend_angle_deg"], preset.spacing)
        radius = np.full(len(pts), preset.radius)
        attrs = {"vessel": "bent tube", "leg_in": preset.leg_in, **shape}
    else:
        rng = np.random.default_rng([seed, index, 1])
        clearance = 2.0 * max(preset.radius, preset.radius_end) * (1 + preset.wobble) + 0.5
        pts = geo.tortuous_points(
            rng, preset.length, preset.min_bend_radius, preset.spacing, clearance
        )
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        radius = geo.radius_profile(arc, preset.radius, preset.radius_end, preset.wobble, rng)
        attrs = {
            "vessel": "tortuous",
            "vessel_length": float(arc[-1]),
            "min_bend_radius": preset.min_bend_radius,
            "radius_start": preset.radius,
            "radius_end": preset.radius_end,
            "radius_wobble": preset.wobble,
        }
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    u = np.clip((arc - arc[-1] + preset.outlet_flare_length) / preset.outlet_flare_length, 0, 1)
    radius = radius * (1.0 + preset.outlet_flare * u**2)
    attrs |= {
        "outlet_flare": preset.outlet_flare,
        "outlet_flare_length": preset.outlet_flare_length,
    }
    return geo.make_centreline(pts, radius), attrs


def _draw(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _bend_shape(preset: Preset, index: int, seed: int) -> dict[str, float]:
    """The bend's outlet leg, bend radius and angle of simulation ``index``: the preset's, or
    drawn from its ``*_range`` fields (stream ``[seed, index, 1]``, in that order)."""
    rng = np.random.default_rng([seed, index, 1])
    pick = lambda bounds, fixed: fixed if bounds is None else _draw(rng, bounds)  # noqa: E731
    return {"leg_out": pick(preset.leg_out_range, preset.leg_out),
            "bend_radius": pick(preset.bend_radius_range, preset.bend_radius),
            "bend_angle_deg": pick(preset.bend_angle_range, preset.bend_angle_deg)}


def build_case(preset: Preset, index: int, seed: int) -> Case:
    """Build simulation ``index`` of ``preset`` from ``seed`` (see the module docstring).

    Returns:
        :class:`Case` whose ``params.dt`` is the stable substep.
    """
    rng = np.random.default_rng([seed, index])
    drawn = {
        "clot_start": _draw(rng, preset.clot_start_range),
        "roll_deg": _draw(rng, preset.roll_range),
        "oversize": _draw(rng, preset.oversize_range),
        "friction": _draw(rng, preset.friction_range),
        "drive_ratio": _draw(rng, preset.drive_ratio_range),
        "flow_speed": _draw(rng, preset.flow_speed_range),
        "young": _draw(rng, preset.young_range),
        "poisson": _draw(rng, preset.poisson_range),
    }
    cl, vessel_attrs = build_vessel(preset, index, seed)
    s_back = drawn["clot_start"] + (preset.leg_in if preset.kind == "bend" else 0.0)
    arc, radius = np.asarray(cl.arc), np.asarray(cl.radius)
    r_ref = float(np.interp(s_back + 0.5 * preset.clot_length, arc, radius))
    os_ = drawn["oversize"]
    rest_radius = os_ * r_ref
    stretch = (os_ / preset.squeeze) ** 2  # isochoric placement: radial squeeze, axial stretch
    rest, tets = clotmesh.cylinder_mesh(
        preset.clot_cross, preset.clot_cells, rest_radius, preset.clot_length / stretch
    )
    x0 = clotmesh.place_clot(
        rest, cl, s_back, rest_radius, preset.clot_length, drawn["roll_deg"], preset.squeeze
    )
    mu, kappa = lame(drawn["young"], drawn["poisson"])
    pressure = mu * (os_**4 - os_**-2)
    k_contact = max(pressure, preset.min_contact_pressure * drawn["young"]) / (
        preset.penetration_target * r_ref
    )
    g_hold = 2.0 * drawn["friction"] * pressure / r_ref
    drive = max(drawn["drive_ratio"] * g_hold, preset.min_alpha * drawn["flow_speed"])
    alpha = drive / drawn["flow_speed"]
    ref = reference_data(rest, tets)
    f = lambda a: jnp.asarray(np.asarray(a, np.float64))  # noqa: E731 (x64-aware dtype)
    params = CaseParams(
        x0=f(x0), seg0=jnp.asarray(geo.signed_distance_np(cl, x0)["seg"], jnp.int32),
        dm_inv=f(ref["dm_inv"]), vol0=f(ref["vol0"]), vol0_node=f(ref["vol0_node"]),
        mass=f(clotmesh.lumped_masses(rest, tets)), area=f(clotmesh.nodal_areas(x0, tets)),
        mu=f(mu), kappa=f(kappa), k_contact=f(k_contact),
        zeta=f(preset.contact_damping), friction=f(drawn["friction"]), drive=f(drive),
        ramp_time=f(preset.ramp_time), alpha=f(alpha), dt=f(0.0),
        exit_margin=f(preset.exit_margin), pen_cap=f(preset.penetration_cap),
    )  # fmt: skip
    dt = stable_dt(params, jnp.asarray(tets), safety=preset.safety, elem_bulk=preset.elem_bulk)
    params = params.replace(dt=dt)
    h_min = float(min(clotmesh.tet_min_heights(rest, tets).min(),
                      clotmesh.tet_min_heights(x0, tets).min()))  # fmt: skip
    wall_pts, wall_cells = geo.wall_mesh(cl, preset.wall_rings, preset.wall_around)
    rotation_deg = float(index * preset.rotation_step_deg) if preset.kind == "bend" else 0.0
    attrs = {
        **drawn, **vessel_attrs, "index": int(index), "seed": int(seed),
        "rotation_deg": rotation_deg, "rotation_axis": preset.rotation_axis,
        "clot_length": preset.clot_length, "clot_rest_radius": rest_radius,
        "clot_rest_length": preset.clot_length / stretch, "local_radius": r_ref,
        "drive": drive, "damping_alpha": alpha, "contact_pressure_estimate": pressure,
        "contact_stiffness": k_contact,
        "shear_modulus": mu, "bulk_modulus": kappa, "substep_dt": float(params.dt),
        "substep_dt_wave_estimate": h_min / np.sqrt(kappa + 4.0 * mu / 3.0),
    }  # fmt: skip
    return Case(
        index=int(index), params=params, centreline=cl, tets=tets, wall_points=wall_pts,
        wall_cells=wall_cells, rotation=geo.rotation_matrix(preset.rotation_axis, rotation_deg),
        attrs=attrs,
    )  # fmt: skip


def stack_cases(cases: list[Case]) -> CaseParams:
    """Stack the params of cases with identical meshes along a new leading axis (for vmap)."""
    return jax.tree.map(lambda *a: jnp.stack(a), *[c.params for c in cases])
