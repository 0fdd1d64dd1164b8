"""Clot mesh (no slivers, conforming), placement, lumped quantities and the material energy."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.sim import clot, geometry, material


@pytest.fixture(scope="module")
def mesh():
    return clot.cylinder_mesh(4, 10, 1.1, 3.0)


def test_counts_volume_and_quality(mesh):
    x, tets = mesh
    assert x.shape == (275, 3) and tets.shape == (960, 4)
    vol = clot.tet_volumes(x, tets)
    assert np.all(vol > 0)
    assert vol.sum() == pytest.approx(np.pi * 1.1**2 * 3.0, rel=0.03)
    assert vol.min() / vol.mean() > 0.5  # no slivers
    h = clot.tet_min_heights(x, tets)
    assert h.min() > 0.5 * h.mean()
    big = clot.cylinder_mesh(12, 30, 1.1, 5.0)
    assert big[0].shape[0] == 5239 and big[1].shape[0] == 25920
    assert clot.tet_volumes(*big).min() / clot.tet_volumes(*big).mean() > 0.5


def test_mesh_is_conforming_and_closed(mesh):
    _, tets = mesh
    faces = np.sort(
        np.concatenate(
            [tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]]
        ),
        axis=1,
    )
    _, counts = np.unique(faces, axis=0, return_counts=True)
    assert counts.max() == 2  # every face shared by at most two tets
    tri = clot.surface_triangles(tets)
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    _, ecount = np.unique(edges, axis=0, return_counts=True)
    assert np.all(ecount == 2)  # the boundary is a closed surface


def test_areas_and_masses(mesh):
    x, tets = mesh
    area = clot.nodal_areas(x, tets)
    exact = 2 * np.pi * 1.1 * 3.0 + 2 * np.pi * 1.1**2
    assert area.sum() == pytest.approx(exact, rel=0.03)
    assert np.sum(area > 0) < len(x)  # interior nodes carry no contact area
    assert clot.lumped_masses(x, tets, 2.0).sum() == pytest.approx(
        2.0 * clot.tet_volumes(x, tets).sum()
    )


def test_placement_in_bend(mesh):
    x, _ = mesh
    pts = geometry.bent_tube_points(5.0, 10.0, 3.0, 90.0, 0.2)
    cl = geometry.make_centreline(pts, np.full(len(pts), 1.0))
    placed = clot.place_clot(x, cl, 6.0, 1.1, 3.0, 30.0, 0.97)
    d = geometry.signed_distance_np(cl, placed)
    assert d["phi"].min() == pytest.approx(0.03, abs=0.01)  # squeezed to 0.97 r, no contact
    with pytest.raises(ConfigError):
        clot.place_clot(x, cl, cl.length - 1.0, 1.1, 3.0, 0.0, 0.97)


def test_energy_rest_rotation_and_forces(mesh):
    x, tets = mesh
    ref = material.reference_data(x, tets)
    mu, kappa = material.lame(1.0, 0.49)
    args = (jnp.asarray(tets), ref["dm_inv"], ref["vol0"], ref["vol0_node"], mu, kappa)
    energy = jax.jit(lambda y: material.elastic_energy(jnp.asarray(y), *args))  # one program
    assert abs(float(energy(x))) < 1e-4
    assert np.abs(np.asarray(jax.grad(energy)(jnp.asarray(x)))).max() < 1e-4
    rot = geometry.rotation_matrix("y", 37.0)
    rng = np.random.default_rng(0)
    y = x + 0.05 * rng.normal(size=x.shape)
    assert float(energy(y @ rot.T)) == pytest.approx(float(energy(y)), rel=1e-4)
    assert float(energy(0.9 * x)) > 0 and float(energy(y)) > 0
    j = material.element_J(jnp.asarray(0.9 * x), jnp.asarray(tets), ref["dm_inv"])
    np.testing.assert_allclose(np.asarray(j), 0.729, rtol=1e-4)


def test_averaged_pressure_relieves_locking():
    """The softest deformation modes of a near-incompressible bar stay soft (no locking)."""
    x, tets = clot.cylinder_mesh(2, 8, 0.5, 4.0)
    ref = material.reference_data(x, tets)

    def bending(nu, elem_bulk):
        mu, kappa = material.lame(1.0, nu)

        def energy(flat):
            return material.elastic_energy(
                flat.reshape(-1, 3),
                jnp.asarray(tets),
                ref["dm_inv"],
                ref["vol0"],
                ref["vol0_node"],
                mu,
                kappa,
                elem_bulk,
            )

        hess = jax.jit(jax.jacfwd(jax.grad(energy)))(jnp.asarray(x.ravel()))
        return np.linalg.eigvalsh(np.asarray(hess, np.float64))[6]  # first non-rigid mode

    locked = bending(0.499, np.inf) / bending(0.45, np.inf)  # all per element
    relieved = bending(0.499, 0.0) / bending(0.45, 0.0)  # pure nodal pressure
    blended = bending(0.499, 4.0) / bending(0.45, 4.0)  # the solver's default
    assert locked > 2.0
    assert relieved < 1.2 and blended < 1.2
