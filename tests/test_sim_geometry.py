"""Vessel geometry: centrelines, radius profiles, wall rings, signed distance (numpy vs jax)."""

import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.sim import geometry as geo


@pytest.fixture(scope="module")
def bent():
    pts = geo.bent_tube_points(5.0, 10.0, 3.0, 90.0, 0.2)
    return geo.make_centreline(pts, np.full(len(pts), 1.0))


def test_bent_tube_length_and_ends(bent):
    assert bent.length == pytest.approx(5 + 10 + 3 * np.pi / 2, rel=2e-3)
    np.testing.assert_allclose(bent.points[0], [0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(bent.points[-1], [8, 13, 0], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(bent.tangent, axis=1), 1.0, atol=1e-12)


def test_signed_distance_of_known_points(bent):
    x = np.array([[2.0, 0.0, 0.0], [2.0, 0.5, 0.0], [2.0, 0.0, 1.3], [-0.5, 0, 0], [8, 13.7, 0]])
    d = geo.signed_distance_np(bent, x)
    np.testing.assert_allclose(d["phi"][:3], [1.0, 0.5, -0.3], atol=1e-9)
    assert d["outside"].tolist() == [False, False, False, True, True]
    assert d["beyond"][4] == pytest.approx(0.7)


def test_local_search_matches_brute_force(bent):
    rng = np.random.default_rng(0)
    s = rng.uniform(0.5, bent.length - 0.5, 300)
    c = np.stack([np.interp(s, bent.arc, bent.points[:, k]) for k in range(3)], 1)
    x = c + rng.normal(scale=0.5, size=c.shape)
    ref = geo.signed_distance_np(bent, x)
    # start the tracking one segment off, as after a substep
    guess = np.clip(ref["seg"] + rng.integers(-1, 2, len(x)), 0, len(bent.seg_len) - 1)
    cl = geo.Centreline(
        *(jnp.asarray(a) for a in (bent.points, bent.radius, bent.tangent, bent.seg_len, bent.arc))
    )
    got = geo.nearest_segment(cl, jnp.asarray(x), jnp.asarray(guess, jnp.int32))
    np.testing.assert_allclose(np.asarray(got["phi"]), ref["phi"], atol=1e-5)
    assert np.array_equal(~np.asarray(got["inside"]), ref["outside"])
    n = np.asarray(got["normal"])
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)


def test_wall_rings_lie_on_the_wall():
    rng = np.random.default_rng(3)
    pts = geo.tortuous_points(rng, 30.0, 3.0, 0.25, 3.0)
    arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    cl = geo.make_centreline(pts, geo.radius_profile(arc, 1.0, 1.18, 0.06, rng))
    wall, tris = geo.wall_mesh(cl, 40, 16)
    assert wall.shape == (640, 3) and tris.shape == (2 * 39 * 16, 3)
    assert tris.min() == 0 and tris.max() == 639
    inner = wall[16:-16]  # the end rings sit exactly on the end planes
    phi = geo.signed_distance_np(cl, inner)["phi"]
    assert np.abs(phi).max() < 0.02


def test_tortuous_curve_bends_gently_and_avoids_itself():
    rng = np.random.default_rng(7)
    pts = geo.tortuous_points(rng, 60.0, 3.0, 0.25, 3.0)
    assert pts.shape == (241, 3)
    e = np.diff(pts, axis=0)
    ds = np.linalg.norm(e, axis=1)
    t = e / ds[:, None]
    angle = np.arccos(np.clip(np.sum(t[1:] * t[:-1], axis=1), -1, 1))
    assert np.max(angle / ds[1:]) <= 1 / 3.0 * 1.05  # curvature radius >= 3
    assert np.degrees(angle.sum()) > 180  # it is actually tortuous
    s = np.concatenate([[0], np.cumsum(ds)])
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    far = np.abs(s[:, None] - s[None]) > 9.0
    assert dist[far].min() >= 3.0
    again = geo.tortuous_points(np.random.default_rng(7), 60.0, 3.0, 0.25, 3.0)
    np.testing.assert_array_equal(pts, again)


def test_radius_profile_range():
    arc = np.linspace(0, 60, 241)
    r = geo.radius_profile(arc, 1.0, 1.18, 0.06, np.random.default_rng(1))
    assert r[0] == pytest.approx(1.0)
    assert np.all(r >= 0.94) and np.all(r <= 1.18 * 1.06 + 1e-9)


def test_rotation_and_bad_input():
    m = geo.rotation_matrix("x", 30.0)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(m @ [1, 0, 0], [1, 0, 0])
    with pytest.raises(ConfigError):
        geo.make_centreline(np.zeros((1, 3)), np.ones(1))
