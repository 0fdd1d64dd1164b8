"""Metrics: MSE conventions, horizons, centroid error and the vessel-containment test."""

from __future__ import annotations

import numpy as np
import pytest

from thrombojax.errors import DatasetError
from thrombojax.eval.metrics import (
    centroid_error,
    fit_vessel_wall,
    fraction_outside,
    horizon_mse,
    mse_per_step,
)
from thrombojax.types import NodeType, clot_mask


def _bent_tube(radius=1.0, bend=4.0, n_ring=16, n_len=30):
    """Wall nodes of a tube: straight leg along x, a 90 deg bend, straight leg along y."""
    phi = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    pts = []
    for s in np.linspace(-6, 0, n_len // 2, endpoint=False):  # leg 1: axis (s, 0, 0)
        pts.append(np.stack([np.full_like(phi, s), radius * np.cos(phi), radius * np.sin(phi)], 1))
    for th in np.linspace(0, np.pi / 2, n_len // 2):  # bend about centre (0, bend, 0)
        c = np.array([bend * np.sin(th), bend - bend * np.cos(th), 0.0])
        e_r = np.array([np.sin(th), -np.cos(th), 0.0])
        ring = c + radius * (np.cos(phi)[:, None] * e_r + np.sin(phi)[:, None] * [0, 0, 1])
        pts.append(ring)
    return np.concatenate(pts)


def test_mse_horizons_and_centroid():
    true = np.zeros((12, 4, 3))
    pred = true.copy()
    pred[:, 0] += np.arange(1, 13)[:, None]  # node 0 (clot) drifts by k
    pred[:, 3] += 100.0  # a vessel node: must not count
    node_type = np.array([NodeType.CLOT, NodeType.CLOT, NodeType.VESSEL, NodeType.VESSEL])
    clot = clot_mask(node_type)
    per = mse_per_step(pred, true, clot)
    np.testing.assert_allclose(per, np.arange(1, 13) ** 2 * 3 / 6)
    h = horizon_mse(per, (1, 10, 50))
    assert set(h) == {"mse@1", "mse@10", "mse@full"}
    assert h["mse@1"] == pytest.approx(per[0]) and h["mse@10"] == pytest.approx(per[:10].mean())
    np.testing.assert_allclose(centroid_error(pred, true, clot), np.arange(1, 13) * np.sqrt(3) / 2)
    with pytest.raises(DatasetError):
        mse_per_step(pred[:3], true, clot)


def test_containment_in_bent_tube():
    wall = _bent_tube()
    inside = np.array([[-3.0, 0.3, 0.2], [-1.0, -0.5, 0.0], [2.8, 1.2, 0.4], [4.0, 4.0, -0.6]])
    outside = np.array([[-3.0, 1.6, 0.0], [-2.0, 0.0, -1.5], [1.2, 2.5, 0.1], [4.0, 4.0, 1.7],
                        [2.6, 1.0, 1.5]])
    n_wall = wall.shape[0]
    positions = np.concatenate([wall, inside, outside])
    node_type = np.array([NodeType.VESSEL] * n_wall + [NodeType.CLOT] * 9)
    vw = fit_vessel_wall(positions, node_type)
    # all normals point away from the axis: dot with (wall - centre of its ring) > 0 on leg 1
    leg1 = wall[:, 0] < -0.5
    radial = wall[leg1] * [0, 1, 1]
    assert (np.einsum("ij,ij->i", vw.normals[:len(wall)][leg1], radial) > 0).all()
    traj = positions[None]
    sel = np.zeros(len(positions), bool)
    sel[n_wall:n_wall + 4] = True
    assert fraction_outside(vw, traj, sel)[0] == 0.0
    sel[:] = False
    sel[n_wall + 4:] = True
    assert fraction_outside(vw, traj, sel)[0] == 1.0
    sel = clot_mask(node_type)
    assert fraction_outside(vw, traj, sel)[0] == pytest.approx(5 / 9)


def _tube_mesh(n_ring=12, n_len=10, radius=1.0, length=6.0):
    """A straight open tube along x as a triangulated ring grid (coarse, like bendvessel-tiny)."""
    phi = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    xs = np.linspace(0, length, n_len)
    pts = np.array([[x, radius * np.cos(p), radius * np.sin(p)] for x in xs for p in phi])
    tris = []
    for i in range(n_len - 1):
        for j in range(n_ring):
            a, b = i * n_ring + j, i * n_ring + (j + 1) % n_ring
            tris += [[a, b, a + n_ring], [b, b + n_ring, a + n_ring]]
    return pts, np.asarray(tris)


def test_containment_with_wall_mesh_and_open_ends():
    wall, tris = _tube_mesh()
    clot = np.array([[3.0, 0.2, 0.1],     # inside
                     [3.0, 1.6, 0.0],     # through the wall
                     [7.5, 1.3, 0.0],     # past the open outlet, expanded: not outside
                     [-1.0, 0.0, -1.4]])  # past the inlet: not outside
    positions = np.concatenate([clot, wall])
    node_type = np.array([NodeType.CLOT] * 4 + [NodeType.VESSEL] * len(wall))
    vw = fit_vessel_wall(positions, node_type, wall_cells=tris + 4)
    rim = np.linalg.norm(vw.rim_dir, axis=1) > 0
    assert rim.sum() == 24 and set(np.unique(vw.points[rim, 0])) == {0.0, 6.0}
    assert (vw.rim_dir[rim & (vw.points[:, 0] == 6.0), 0] > 0.9).all()  # out of the outlet
    assert (vw.rim_dir[rim & (vw.points[:, 0] == 0.0), 0] < -0.9).all()
    out = [fraction_outside(vw, positions[None], np.arange(len(positions)) == i)[0]
           for i in range(4)]
    assert out == [0.0, 1.0, 0.0, 0.0]
    with pytest.raises(DatasetError):
        fit_vessel_wall(positions, node_type, wall_cells=tris)  # indices hit clot nodes


def test_past_an_open_end_as_the_guards_decide_it():
    """With wall triangles, a node leaves through an open end exactly when the guards' exact
    wall query says so (``past_end``); the per-node rim test disagrees on an irregular mesh."""
    import jax.numpy as jnp

    from thrombojax.eval.metrics import VesselWall, signed_wall_distance
    from thrombojax.simulator.wall import nearest_wall_point
    from thrombojax.simulator.wall_build import wall_from_simulation

    rng = np.random.default_rng(0)
    wall, tris = _tube_mesh(n_ring=16, n_len=13)
    wall = wall + rng.normal(0.0, 0.04, wall.shape)  # irregular, as a solver's mesh
    positions = np.concatenate([[[3.0, 0.0, 0.0]], wall])
    node_type = np.array([NodeType.CLOT] + [NodeType.VESSEL] * len(wall))
    vw = fit_vessel_wall(positions, node_type, wall_cells=tris + 1)
    guard_wall = wall_from_simulation(positions, node_type, tris + 1, block_size=16)
    n = 600  # points around the outlet (x = 6), outside the tube's radius
    x, r, phi = rng.uniform(5.6, 6.4, n), rng.uniform(1.1, 2.0, n), rng.uniform(0, 2 * np.pi, n)
    p = np.stack([x, r * np.cos(phi), r * np.sin(phi)], axis=1)
    dist, past = signed_wall_distance(vw, p, return_past_end=True)
    guards = np.asarray(nearest_wall_point(jnp.asarray(p, jnp.float32), guard_wall).past_end)
    out = dist > 0.5 * vw.spacing
    assert out.sum() > 400 and 50 < guards[out].sum() < out.sum() - 50  # both kinds occur
    np.testing.assert_array_equal(past[out], guards[out])
    # the point-cloud test (no triangles) decides some of these nodes otherwise
    cloud = VesselWall(points=vw.points, normals=vw.normals, rim_dir=vw.rim_dir,
                       spacing=vw.spacing)
    assert (signed_wall_distance(cloud, p, return_past_end=True)[1][out] != guards[out]).sum() > 5
