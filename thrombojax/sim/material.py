"""Compressible Neo-Hookean energy of linear tets with an averaged-pressure volumetric term.

Energy (total Lagrangian, per unit reference volume)::

    W = mu/2 (J_e^(-2/3) I1 - 3)                      deviatoric, per element
      + kappa/2 (ln J)^2                               volumetric

Linear tets lock in the volumetric term near incompressibility (one constraint per element,
~6 elements per node). We use the average nodal pressure (ANP) idea of Bonet & Burton (1998,
Comm. Numer. Meth. Eng. 14): the volumetric energy is evaluated with nodal volume ratios
``J_n = (sum of current volumes of the tets around n) / (sum of their rest volumes)``, one
constraint per node, which removes locking. Pure ANP leaves element-level volume modes
unresisted (single tets can collapse), so a part ``kappa_e = min(kappa, elem_bulk * mu)`` of the
bulk modulus is kept per element (``J_e``) and only ``kappa - kappa_e`` goes to the nodes. With
``elem_bulk = 4`` the element part is the bulk modulus of a solid with nu ~ 0.38, which does not
lock, whatever the clot's nu. Forces are ``-jax.grad`` of the total energy, so they are
consistent with it by construction.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["lame", "reference_data", "element_J", "elastic_energy", "DEFAULT_ELEM_BULK"]

DEFAULT_ELEM_BULK = 4.0


def lame(young: float, poisson: float) -> tuple[float, float]:
    """Shear and bulk moduli ``(mu, kappa)`` from Young's modulus and Poisson's ratio."""
    return young / (2.0 * (1.0 + poisson)), young / (3.0 * (1.0 - 2.0 * poisson))


def reference_data(rest: np.ndarray, tets: np.ndarray) -> dict[str, np.ndarray]:
    """Inverse reference edge matrices and rest volumes.

    Args:
        rest: ``[N, 3]`` rest positions.
        tets: ``[C, 4]`` positively oriented tets.

    Returns:
        dict with ``dm_inv [C, 3, 3]`` (inverse of the matrix whose columns are the rest edges
        ``X1-X0, X2-X0, X3-X0``), ``vol0 [C]`` and ``vol0_node [N]`` (a quarter of each adjacent
        rest volume).
    """
    dm = np.swapaxes(rest[tets[:, 1:]] - rest[tets[:, :1]], 1, 2)
    vol0 = np.linalg.det(dm) / 6.0
    vol0_node = np.zeros(len(rest))
    np.add.at(vol0_node, tets.ravel(), np.repeat(vol0 / 4.0, 4))
    return {"dm_inv": np.linalg.inv(dm), "vol0": vol0, "vol0_node": vol0_node}


def _det3(f: jnp.ndarray) -> jnp.ndarray:
    return (
        f[:, 0, 0] * (f[:, 1, 1] * f[:, 2, 2] - f[:, 1, 2] * f[:, 2, 1])
        - f[:, 0, 1] * (f[:, 1, 0] * f[:, 2, 2] - f[:, 1, 2] * f[:, 2, 0])
        + f[:, 0, 2] * (f[:, 1, 0] * f[:, 2, 1] - f[:, 1, 1] * f[:, 2, 0])
    )


def _deformation_gradient(x: jnp.ndarray, tets: jnp.ndarray, dm_inv: jnp.ndarray) -> jnp.ndarray:
    xe = x[tets]
    ds = jnp.swapaxes(xe[:, 1:] - xe[:, :1], 1, 2)
    return ds @ dm_inv


def element_J(x: jnp.ndarray, tets: jnp.ndarray, dm_inv: jnp.ndarray) -> jnp.ndarray:
    """Volume ratio ``J = det F`` per tet ``[C]`` at positions ``x [N, 3]``."""
    return _det3(_deformation_gradient(x, tets, dm_inv))


def elastic_energy(
    x: jnp.ndarray,
    tets: jnp.ndarray,
    dm_inv: jnp.ndarray,
    vol0: jnp.ndarray,
    vol0_node: jnp.ndarray,
    mu: jnp.ndarray,
    kappa: jnp.ndarray,
    elem_bulk: float = DEFAULT_ELEM_BULK,
) -> jnp.ndarray:
    """Total elastic energy (scalar) of the clot.

    Args:
        x: ``[N, 3]`` current positions.
        tets: ``[C, 4]`` tets; dm_inv ``[C, 3, 3]``, vol0 ``[C]``, vol0_node ``[N]`` from
            :func:`reference_data`.
        mu, kappa: shear and bulk moduli (scalars).
        elem_bulk: the per-element bulk modulus is ``min(kappa, elem_bulk * mu)``; the rest of
            ``kappa`` acts on nodal volume ratios (``inf``: all per element, 0: pure ANP).

    Returns:
        ``[]`` energy.
    """
    f = _deformation_gradient(x, tets, dm_inv)
    j = _det3(f)
    i1 = jnp.sum(f * f, axis=(1, 2))
    w_dev = 0.5 * mu * (i1 * jnp.cbrt(j) ** -2 - 3.0)
    vol_node = jax.ops.segment_sum(
        jnp.repeat(j * vol0 / 4.0, 4), tets.reshape(-1), num_segments=x.shape[0]
    )
    j_node = vol_node / vol0_node
    kappa_e = jnp.minimum(kappa, elem_bulk * mu)
    u_node = 0.5 * (kappa - kappa_e) * jnp.log(j_node) ** 2
    u_elem = 0.5 * kappa_e * jnp.log(j) ** 2
    return jnp.sum(vol0 * (w_dev + u_elem)) + jnp.sum(vol0_node * u_node)
