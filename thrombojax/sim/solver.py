"""Explicit dynamics of a clot driven through a rigid vessel (jitted; vmappable over cases).

One substep (semi-implicit Euler, lumped mass ``m``)::

    f   = -grad E(x)                                   elastic forces (material.py)
        - (k A pen + c vn) n                           wall penalty + normal damping, n outward
    a   = f / m + g(t) t(x)                            drive: body acceleration along the tangent
    v*  = (v + dt a) / (1 + alpha dt)                  mass-proportional damping, implicit
    v_n <= (phi + pen_cap r) / dt                      hard penetration cap (rarely active)
    v'  = Coulomb cap on the tangential part of v*     stick if |v_t| <= mu (dt k A pen / m
                                                                              + cut v_n)
    x'  = x + dt v'

The penalty stiffness per unit area ``k`` comes from the expected contact pressure and a
target penetration (``cases.py``), not from ``dt``; ``A`` is the node's boundary area, so
the wall pressure does not depend on the mesh size. The substep is
``dt = safety * 2 / omega_max`` with ``omega_max^2`` the largest eigenvalue of ``M^-1 K`` at
the (pre-stressed) start, found by power iteration on Hessian-vector products, plus the
largest contact ``k A / m`` (:func:`stable_dt`). This is the exact limit of the linearised
system, mesh, material (with its nodal/element split of the bulk modulus) and contact included;
the classic ``smallest tet height / dilatational wave speed`` rule is a heuristic that here comes
out 1.1-1.6x larger than ``2 / omega_max``, so it is only recorded
(``substep_dt_wave_estimate``) for comparison. ``safety`` (0.5 - 0.65) covers the stiffening of
compressed tets during the run.

:func:`run` advances until every clot node has passed the vessel outlet by ``exit_margin``
(``lax.while_loop`` over chunks of ``stride`` substeps, a ``lax.fori_loop`` each, with a cap
``max_substeps``). A frame is stored after every chunk into a buffer of ``n_buffer`` (odd)
frames; when it is full, every other frame is dropped and ``stride`` doubles, so any run ends
with between ``(n_buffer + 1) / 2`` and ``n_buffer`` frames equally spaced in time, whatever
its length. The host then resamples them to the preset's frame count.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from flax import struct

from thrombojax.sim.geometry import Centreline, nearest_segment
from thrombojax.sim.material import DEFAULT_ELEM_BULK, elastic_energy

__all__ = ["CaseParams", "RunResult", "energy_fn", "stable_dt", "run", "run_batch"]


@struct.dataclass
class CaseParams:
    """Everything that varies between simulations of one preset (stack along axis 0 to vmap).

    Attributes:
        x0: ``[N, 3]`` initial clot positions.
        seg0: ``[N]`` int32 initial nearest centreline segment.
        dm_inv: ``[C, 3, 3]``; vol0 ``[C]``; vol0_node ``[N]``: rest data (material.py).
        mass: ``[N]`` lumped masses; area ``[N]`` boundary area per node.
        mu, kappa: shear and bulk moduli; k_contact: penalty stiffness per unit area;
        zeta: contact damping ratio; friction: Coulomb coefficient; drive: final body
        acceleration; ramp_time: time of the linear drive ramp; alpha: mass damping;
        dt: substep; exit_margin: distance past the outlet that counts as "out";
        pen_cap: largest penetration / radius allowed (normal velocity clamp).
    """

    x0: jnp.ndarray
    seg0: jnp.ndarray
    dm_inv: jnp.ndarray
    vol0: jnp.ndarray
    vol0_node: jnp.ndarray
    mass: jnp.ndarray
    area: jnp.ndarray
    mu: jnp.ndarray
    kappa: jnp.ndarray
    k_contact: jnp.ndarray
    zeta: jnp.ndarray
    friction: jnp.ndarray
    drive: jnp.ndarray
    ramp_time: jnp.ndarray
    alpha: jnp.ndarray
    dt: jnp.ndarray
    exit_margin: jnp.ndarray
    pen_cap: jnp.ndarray


@struct.dataclass
class RunResult:
    """Output of :func:`run` (add a leading batch axis under :func:`run_batch`).

    Attributes:
        frames: ``[n_buffer, N, 3]`` stored positions; the first ``count`` are valid, frame
            ``k`` at time ``k * stride * dt``.
        kinetic: ``[n_buffer]``; elastic ``[n_buffer]``: energies of the stored frames;
        inside: ``[n_buffer]`` fraction of clot nodes inside the vessel (not past an end).
        count: number of valid frames; stride: substeps between stored frames.
        steps: substeps run; exited: whether the clot left the vessel.
        max_penetration: largest wall penetration over all substeps, relative to the radius.
    """

    frames: jnp.ndarray
    kinetic: jnp.ndarray
    elastic: jnp.ndarray
    inside: jnp.ndarray
    count: jnp.ndarray
    stride: jnp.ndarray
    steps: jnp.ndarray
    exited: jnp.ndarray
    max_penetration: jnp.ndarray


def energy_fn(p: CaseParams, tets: jnp.ndarray, elem_bulk: float = DEFAULT_ELEM_BULK):
    """``x [N, 3] -> []`` the clot's elastic energy for case ``p``."""
    return lambda x: elastic_energy(
        x, tets, p.dm_inv, p.vol0, p.vol0_node, p.mu, p.kappa, elem_bulk
    )


@functools.partial(jax.jit, static_argnames=("elem_bulk", "iters"))
def stable_dt(
    p: CaseParams,
    tets: jnp.ndarray,
    *,
    safety: float,
    elem_bulk: float = DEFAULT_ELEM_BULK,
    iters: int = 60,
) -> jnp.ndarray:
    """Stable explicit substep ``safety * 2 / sqrt(lambda_el + lambda_contact)``.

    ``lambda_el`` is the largest eigenvalue of ``M^-1/2 H M^-1/2`` at ``p.x0`` (power iteration
    with Hessian-vector products, 5 % added for its slow convergence); ``lambda_contact`` the
    largest ``k_contact * area / mass``. Jittable; ``p.dt`` is ignored.
    """
    grad = jax.grad(energy_fn(p, tets, elem_bulk))
    s = 1.0 / jnp.sqrt(p.mass)[:, None]

    def hvp(u):
        return s * jax.jvp(grad, (p.x0,), (s * u,))[1]

    def body(_, u):
        w = hvp(u)
        return w / jnp.linalg.norm(w)

    u0 = jnp.sin(jnp.arange(p.x0.size, dtype=p.x0.dtype) * 1.618).reshape(p.x0.shape)
    u = jax.lax.fori_loop(0, iters, body, u0 / jnp.linalg.norm(u0))
    lam = 1.05 * jnp.sum(u * hvp(u))
    lam_c = jnp.max(p.k_contact * p.area / p.mass)
    return safety * 2.0 / jnp.sqrt(lam + lam_c)


def _substep(p: CaseParams, cl: Centreline, grad, carry):
    x, v, seg, step, pen_max = carry
    geo = nearest_segment(cl, x, seg)
    pen = jnp.where(geo["inside"], jnp.maximum(-geo["phi"], 0.0), 0.0)
    n = geo["normal"]
    kn = p.k_contact * p.area
    fn = kn * pen
    vn = jnp.sum(v * n, axis=1)
    c_n = jnp.where(pen > 0, 2.0 * p.zeta * jnp.sqrt(kn * p.mass), 0.0)
    force = -grad(x) - (fn + c_n * vn)[:, None] * n
    g = p.drive * jnp.minimum(1.0, step * p.dt / p.ramp_time)
    acc = force / p.mass[:, None] + g * geo["tangent"]
    v1 = (v + p.dt * acc) / (1.0 + p.alpha * p.dt)
    vn1 = jnp.sum(v1 * n, axis=1)
    vt = v1 - vn1[:, None] * n
    # hard cap: no node ends the substep deeper than pen_cap * r (linearised wall)
    vn_max = jnp.where(geo["inside"], (geo["phi"] + p.pen_cap * geo["radius"]) / p.dt, jnp.inf)
    vn_cut = jnp.maximum(vn1 - vn_max, 0.0)
    vn1 = vn1 - vn_cut
    speed = jnp.linalg.norm(vt, axis=1)
    cap = p.friction * (p.dt * fn / p.mass + vn_cut)
    keep = jnp.where(speed > cap, 1.0 - cap / jnp.maximum(speed, 1e-30), 0.0)
    v1 = vn1[:, None] * n + keep[:, None] * vt
    pen_max = jnp.maximum(pen_max, jnp.max(pen / geo["radius"]))
    return x + p.dt * v1, v1, geo["seg"], step + 1, pen_max


@functools.partial(jax.jit, static_argnames=("n_buffer", "elem_bulk"))
def run(
    p: CaseParams,
    cl: Centreline,
    tets: jnp.ndarray,
    *,
    n_buffer: int,
    max_substeps: int,
    elem_bulk: float = DEFAULT_ELEM_BULK,
) -> RunResult:
    """Simulate one case until the clot has left the vessel (or ``max_substeps``).

    Args:
        p: the case.
        cl: the vessel centreline.
        tets: ``[C, 4]`` clot tets.
        n_buffer: stored frames (odd; the run ends with ``(n_buffer+1)/2 .. n_buffer``).
        max_substeps: safety cap on the number of substeps (traced: no recompile).
        elem_bulk: cap of the per-element bulk modulus, in shear moduli (material.py).

    Returns:
        :class:`RunResult`.
    """
    if n_buffer % 2 == 0 or n_buffer < 3:
        raise ValueError("n_buffer must be odd and >= 3")
    energy = energy_fn(p, tets, elem_bulk)
    grad = jax.grad(energy)
    dtype = p.x0.dtype
    frames = jnp.zeros((n_buffer,) + p.x0.shape, dtype).at[0].set(p.x0)
    zeros = jnp.zeros((n_buffer,), dtype)
    state = {
        "x": p.x0, "v": jnp.zeros_like(p.x0), "seg": p.seg0, "step": jnp.int32(0),
        "pen": jnp.zeros((), dtype), "frames": frames, "kinetic": zeros,
        "elastic": zeros.at[0].set(energy(p.x0)), "inside": zeros.at[0].set(1.0),
        "count": jnp.int32(1),
        "stride": jnp.int32(1), "exited": jnp.bool_(False),
    }  # fmt: skip

    def cond(s):
        return (~s["exited"]) & (s["step"] < max_substeps)

    def decimate(s):
        half = (n_buffer + 1) // 2
        out = dict(s)
        for key in ("frames", "kinetic", "elastic", "inside"):
            out[key] = s[key].at[:half].set(s[key][::2])
        out["count"] = jnp.int32(half)
        out["stride"] = 2 * s["stride"]
        return out

    def body(s):
        carry = (s["x"], s["v"], s["seg"], s["step"], s["pen"])
        x, v, seg, step, pen = jax.lax.fori_loop(
            0, s["stride"], lambda _, c: _substep(p, cl, grad, c), carry
        )
        k = s["count"]
        out = dict(s, x=x, v=v, seg=seg, step=step, pen=pen, count=k + 1)
        out["frames"] = s["frames"].at[k].set(x)
        out["kinetic"] = s["kinetic"].at[k].set(0.5 * jnp.sum(p.mass[:, None] * v * v))
        out["elastic"] = s["elastic"].at[k].set(energy(x))
        geo = nearest_segment(cl, x, seg)
        out["exited"] = jnp.all(geo["beyond"] > p.exit_margin)
        out["inside"] = s["inside"].at[k].set(jnp.mean(geo["inside"].astype(dtype)))
        return jax.lax.cond(out["count"] == n_buffer, decimate, lambda t: t, out)

    s = jax.lax.while_loop(cond, body, state)
    return RunResult(
        frames=s["frames"], kinetic=s["kinetic"], elastic=s["elastic"], inside=s["inside"],
        count=s["count"],
        stride=s["stride"], steps=s["step"], exited=s["exited"], max_penetration=s["pen"],
    )  # fmt: skip


@functools.partial(jax.jit, static_argnames=("n_buffer", "elem_bulk"))
def run_batch(
    p: CaseParams,
    cl: Centreline,
    tets: jnp.ndarray,
    *,
    n_buffer: int,
    max_substeps: int,
    elem_bulk: float = DEFAULT_ELEM_BULK,
) -> RunResult:
    """:func:`run` vmapped over cases stacked along axis 0 of every field of ``p``.

    The loop runs until every case has exited; finished cases are frozen (their buffers stay
    consistent), so each case's result equals its own :func:`run`.
    """
    fn = functools.partial(run, n_buffer=n_buffer, max_substeps=max_substeps, elem_bulk=elem_bulk)
    return jax.vmap(fn, in_axes=(0, None, None))(p, cl, tets)
