"""Physics guards: containment in the rigid wall (triangles and nodes+normals) and coherence."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from wall_factory import bent_vessel, clot_cloud, radial_push, true_phi

from thrombojax.errors import ConfigError, DatasetError
from thrombojax.sim.geometry import rotation_matrix, signed_distance_np
from thrombojax.simulator.guards import (
    cell_edges,
    coherence,
    contain,
    nearest_wall_point,
    relax_edges,
    wall_from_simulation,
)
from thrombojax.simulator.wall import closest_point_on_triangle
from thrombojax.simulator.walls import fraction_outside_wall

MARGIN = 0.02


@pytest.fixture(scope="module")
def vessel():
    return bent_vessel()


@pytest.fixture(scope="module", params=["triangles", "nodes"])
def wall(request, vessel):
    cells = vessel["wall_cells"] if request.param == "triangles" else None
    w = wall_from_simulation(vessel["positions"], vessel["node_type"], cells, block_size=16,
                             search_blocks=4)
    assert w.kind == request.param
    return w


def _guard(x, clot, wall):
    return jax.jit(lambda y: contain(y, clot, wall, margin=MARGIN))(jnp.asarray(x, jnp.float32))


# penetration depth (vessel radii) a wall may miss: the triangles are chords of the smooth
# vessel (12 around: sagitta 0.034) and tangent planes of wall nodes are cruder
MISSED_DEPTH = {"triangles": 0.05, "nodes": 0.15}


def test_outward_push_leaves_the_vessel_and_contain_brings_it_back(vessel, wall):
    clot = jnp.asarray(vessel["clot"])
    x = radial_push(vessel, 0.6)
    q = jax.jit(lambda y: nearest_wall_point(y, wall))(jnp.asarray(x, jnp.float32))
    flagged = np.asarray(q.signed > q.slack)[vessel["clot"]]
    phi = true_phi(vessel, x)
    assert flagged.mean() > 0.2
    assert (phi[flagged] < 0).all(), "a node inside the smooth vessel counted as outside"
    assert flagged[phi < -MISSED_DEPTH[wall.kind]].all()
    frac = jax.jit(lambda y: fraction_outside_wall(y, clot, wall))
    assert float(frac(jnp.asarray(x, jnp.float32))) == pytest.approx(flagged.mean())
    x_new, corr = _guard(x, clot, wall)
    assert float(frac(x_new)) == 0.0
    q_new = jax.jit(lambda y: nearest_wall_point(y, wall))(x_new)
    assert (np.asarray(q_new.signed)[np.asarray(corr) > 0] < 0).all(), "not inside the facets"
    assert true_phi(vessel, np.asarray(x_new, np.float64)).min() > -MISSED_DEPTH[wall.kind]
    moved = np.asarray(corr) > 0
    np.testing.assert_array_equal(moved[vessel["clot"]], flagged)
    np.testing.assert_allclose(np.linalg.norm(np.asarray(x_new) - x, axis=1), corr, atol=1e-5)
    # wall nodes are never moved
    np.testing.assert_array_equal(np.asarray(x_new)[~vessel["clot"]],
                                  x[~vessel["clot"]].astype(np.float32))


def test_nodes_inside_are_not_moved(vessel, wall):
    x = radial_push(vessel, 0.1)
    assert true_phi(vessel, x).min() > 0.1
    x32 = jnp.asarray(x, jnp.float32)
    x_new, corr = _guard(x, jnp.asarray(vessel["clot"]), wall)
    np.testing.assert_array_equal(np.asarray(corr), 0.0)
    np.testing.assert_array_equal(np.asarray(x_new), np.asarray(x32))


def test_immovable_nodes_outside_are_not_moved(vessel, wall):
    x = radial_push(vessel, 0.6)
    none = jnp.zeros(x.shape[0], bool)
    x_new, corr = _guard(x, none, wall)
    np.testing.assert_array_equal(np.asarray(corr), 0.0)
    np.testing.assert_array_equal(np.asarray(x_new), x.astype(np.float32))


def test_nodes_past_the_open_end_are_not_outside(vessel, wall):
    cl = vessel["centreline"]
    end, tangent = np.asarray(cl.points)[-1], np.asarray(cl.tangent)[-1]
    side = np.cross(tangent, [0.0, 0.0, 1.0])
    x = vessel["positions"].copy()
    n = vessel["clot"].sum()
    # beyond the outlet, some far off the axis (a clot that left the vessel and spread)
    along, across = np.linspace(0.3, 1.0, n)[:, None], np.linspace(-1.5, 1.5, n)[:, None]
    x[:n] = end + along * tangent + across * side
    x_new, corr = _guard(x, jnp.asarray(vessel["clot"]), wall)
    np.testing.assert_array_equal(np.asarray(corr), 0.0)


def test_contain_under_vmap_matches_single_frames(vessel, wall):
    clot = jnp.asarray(vessel["clot"])
    frames = jnp.asarray(np.stack([radial_push(vessel, a) for a in (0.0, 0.4, 0.7)]), jnp.float32)
    batched = jax.jit(jax.vmap(lambda y: contain(y, clot, wall, margin=MARGIN)))(frames)
    for i in range(frames.shape[0]):
        single = _guard(frames[i], clot, wall)
        np.testing.assert_allclose(batched[0][i], single[0], atol=1e-6)
        np.testing.assert_allclose(batched[1][i], single[1], atol=1e-6)
    assert float(batched[1][0].max()) == 0.0 and float(batched[1][2].max()) > 0.0


def test_walls_of_several_simulations_vmap_with_padding(vessel):
    v2 = bent_vessel(seed=1, n_rings=10)
    walls = [wall_from_simulation(v["positions"], v["node_type"], v["wall_cells"],
                                  max_elements=400) for v in (vessel, v2)]
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *walls)
    xs = [radial_push(v, 0.6)[: vessel["clot"].sum()] for v in (vessel, v2)]
    xs = jnp.asarray(np.stack(xs), jnp.float32)
    clot = jnp.ones(xs.shape[1], bool)
    out, corr = jax.jit(jax.vmap(lambda y, w: contain(y, clot, w, margin=MARGIN)))(xs, stacked)
    assert float(corr.min(axis=1).max()) == 0.0 and float(corr.max(axis=1).min()) > 0.0
    single = jax.jit(lambda y, w: (contain(y, clot, w, margin=MARGIN)[0],
                                   fraction_outside_wall(y, clot, w)))
    for i, w in enumerate(walls):
        x_i, _ = single(xs[i], w)
        np.testing.assert_allclose(out[i], x_i, atol=1e-6)
        assert float(single(out[i], w)[1]) == 0.0


def _brute(x, wall):
    verts = np.asarray(wall.vertices)[np.asarray(wall.mask)]
    cp, _ = closest_point_on_triangle(x[:, None], verts[:, 0], verts[:, 1], verts[:, 2], xp=np)
    return np.linalg.norm(x[:, None] - cp, axis=-1).min(axis=1)


def test_triangle_query_is_exact_where_certified(vessel):
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.5, 6.0, (300, 3)).astype(np.float32)
    x[:, 2] = rng.uniform(-1.5, 1.5, 300)
    args = (vessel["positions"], vessel["node_type"], vessel["wall_cells"])
    for blocks, expect_all in ((2, False), (10_000, True)):
        w = wall_from_simulation(*args, block_size=8, search_blocks=blocks)
        q = jax.jit(lambda y, w=w: nearest_wall_point(y, w))(jnp.asarray(x))
        certain = np.asarray(q.certain)
        assert certain.all() == expect_all and certain.mean() > 0.3
        np.testing.assert_allclose(np.asarray(q.distance)[certain], _brute(x, w)[certain],
                                   atol=1e-5)
        assert (np.asarray(q.distance) >= _brute(x, w) - 1e-5).all()
    # tiles (lax.map over rows) and padding change nothing
    padded = wall_from_simulation(*args, max_elements=2 * len(args[2]))
    assert int(padded.mask.sum()) == len(args[2]) < padded.mask.size
    tiled = jax.jit(lambda y: nearest_wall_point(y, padded, tile_rows=64))(jnp.asarray(x))
    np.testing.assert_allclose(tiled.distance, _brute(x, padded), atol=1e-5)
    np.testing.assert_array_equal(np.asarray(tiled.certain), True)


def test_orientation_does_not_depend_on_the_winding(vessel):
    rng = np.random.default_rng(0)
    cells = vessel["wall_cells"].copy()
    flip = rng.random(len(cells)) < 0.5
    cells[flip] = cells[flip][:, [0, 2, 1]]
    x = jnp.asarray(radial_push(vessel, 0.6), jnp.float32)
    clot = jnp.asarray(vessel["clot"])
    ref = wall_from_simulation(vessel["positions"], vessel["node_type"], vessel["wall_cells"])
    mixed = wall_from_simulation(vessel["positions"], vessel["node_type"], cells)
    # inward: the face normals point toward the centreline
    cent = np.asarray(mixed.vertices).mean(axis=1)[np.asarray(mixed.mask)]
    sd = signed_distance_np(vessel["centreline"], cent)
    axis_pt = np.asarray(vessel["centreline"].points)[sd["seg"]]
    normal = np.asarray(mixed.face_normal)[np.asarray(mixed.mask)]
    assert (np.sum((axis_pt - cent) * normal, axis=1) > 0).all()
    np.testing.assert_allclose(_guard(x, clot, mixed)[1], _guard(x, clot, ref)[1], atol=1e-5)


def test_bad_walls_are_rejected(vessel):
    with pytest.raises(DatasetError, match="non-vessel"):
        wall_from_simulation(vessel["positions"], vessel["node_type"], np.array([[0, 1, 2]]))
    with pytest.raises(ConfigError, match="max_elements"):
        wall_from_simulation(vessel["positions"], vessel["node_type"], vessel["wall_cells"],
                             max_elements=10)
    with pytest.raises(DatasetError, match="positions0"):
        wall_from_simulation(vessel["positions"][:, :2], vessel["node_type"])


# ----------------------------------------------------------------------------- coherence

def _rigid(x, angle=35.0, shift=(0.3, -1.0, 2.0)):
    rot = rotation_matrix("z", angle) @ rotation_matrix("x", 20.0)
    return (x @ rot.T + np.asarray(shift)).astype(np.float32), rot


def _pairwise(x):
    return np.linalg.norm(x[:, None] - x[None], axis=-1)


def test_coherence_leaves_a_rigidly_moved_clot_alone():
    ref, mask = clot_cloud()
    x, _ = _rigid(ref)
    x[~mask] = -3.0  # garbage in padded rows
    x_new, corr = jax.jit(lambda a: coherence(a, jnp.asarray(ref), jnp.asarray(mask),
                                              stiffness=1.0))(jnp.asarray(x))
    assert float(np.abs(corr).max()) < 1e-4
    np.testing.assert_array_equal(np.asarray(x_new)[~mask], x[~mask])


def test_coherence_restores_a_stretched_rotatedclot_cloud():
    ref, mask = clot_cloud()
    rigid, _ = _rigid(ref)
    stretched = rigid.copy()
    stretched[mask] = rigid[mask] * [1.5, 0.8, 1.0] + 0.05 * np.random.default_rng(1).normal(
        size=(mask.sum(), 3))
    stretched[~mask] = 9.0
    f = jax.jit(lambda a, s: coherence(a, jnp.asarray(ref), jnp.asarray(mask), stiffness=s))
    full, corr = f(jnp.asarray(stretched), 1.0)
    full = np.asarray(full)
    # a rigid copy of the reference
    np.testing.assert_allclose(_pairwise(full[mask]), _pairwise(ref[mask]), atol=2e-4)
    assert float(corr.max()) > 0.1
    np.testing.assert_array_equal(full[~mask], stretched[~mask])
    np.testing.assert_array_equal(np.asarray(corr)[~mask], 0.0)
    half, corr_half = f(jnp.asarray(stretched), 0.5)
    err = lambda y: np.abs(_pairwise(np.asarray(y)[mask]) - _pairwise(ref[mask])).mean()  # noqa: E731
    assert err(half) < err(stretched)
    np.testing.assert_allclose(corr_half, 0.5 * corr, rtol=1e-4, atol=1e-6)


def test_coherence_never_mirrors_theclot_cloud():
    ref, mask = clot_cloud()
    mirrored = ref.copy()
    mirrored[:, 0] *= -1.0
    out, _ = jax.jit(lambda a: coherence(a, jnp.asarray(ref), jnp.asarray(mask),
                                         stiffness=1.0))(jnp.asarray(mirrored))
    out = np.asarray(out)

    def volumes(y):
        return np.linalg.det(np.stack([y[1:40:3] - y[0], y[2:41:3] - y[0], y[3:42:3] - y[0]], 1))

    np.testing.assert_array_equal(np.sign(volumes(out)), np.sign(volumes(ref)))


def test_coherence_tolerance_allows_small_deviations():
    ref, mask = clot_cloud()
    x = ref + 0.01 * np.random.default_rng(2).normal(size=ref.shape).astype(np.float32)
    f = jax.jit(lambda a, tol: coherence(a, jnp.asarray(ref), jnp.asarray(mask), stiffness=1.0,
                                         tolerance=tol)[1])
    np.testing.assert_array_equal(np.asarray(f(jnp.asarray(x), 0.1)), 0.0)
    assert float(f(jnp.asarray(x), 0.0).max()) > 0.0


def test_coherence_under_vmap():
    ref, mask = clot_cloud()
    xs = np.stack([_rigid(ref, a)[0] * 1.2 for a in (0.0, 60.0)])
    f = lambda a: coherence(a, jnp.asarray(ref), jnp.asarray(mask), stiffness=1.0)  # noqa: E731
    batched = jax.jit(jax.vmap(f))(jnp.asarray(xs))
    for i in range(2):
        np.testing.assert_allclose(batched[0][i], jax.jit(f)(jnp.asarray(xs[i]))[0], atol=1e-5)


def test_relax_edges_brings_strain_within_limits():
    ref, mask = clot_cloud(n_real=8, n_pad=2)
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4], [4, 5, 6, 7]])
    s, r = cell_edges(tets)
    assert len(s) == 6 + 3 + 6  # the two first tets share a face
    x = ref.copy()
    x[mask] *= 1.6
    f = jax.jit(lambda a: relax_edges(a, jnp.asarray(ref), jnp.asarray(s), jnp.asarray(r),
                                      jnp.asarray(mask), max_strain=0.2, iterations=60))
    x_new, corr = f(jnp.asarray(x))
    strain = lambda y: np.abs(np.linalg.norm(y[s] - y[r], axis=1)  # noqa: E731
                              / np.linalg.norm(ref[s] - ref[r], axis=1) - 1)
    assert strain(x).min() > 0.5 and strain(np.asarray(x_new)).max() < 0.21
    np.testing.assert_array_equal(np.asarray(x_new)[~mask], x[~mask])
    _, corr_ok = f(jnp.asarray(ref * 1.1))
    np.testing.assert_array_equal(np.asarray(corr_ok), 0.0)


def test_guards_in_the_compiled_rollout():
    """A model that pushes clot nodes outward: containment on -> 0 % outside, off -> > 0 %;
    corrections are recorded per step, vessel nodes are never moved."""
    from wall_factory import Outward, straight_tube

    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.simulator.rollout import rollout, rollout_with_corrections
    from thrombojax.simulator.walls import fraction_outside_wall
    from thrombojax.types import NodeType, TargetStats

    x0, node_type = straight_tube()
    mask = np.ones(len(x0), bool)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.ones(3))
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0, coherence=False)
    free = np.asarray(rollout(Outward(), {}, stats, x0, x0, node_type, mask, 12))
    traj, corr = rollout_with_corrections(Outward(), {}, stats, x0, x0, node_type, mask, 12,
                                          guards=guards)
    traj, corr = np.asarray(traj), {k: np.asarray(v) for k, v in corr.items()}
    clot_mask = jnp.asarray(node_type == NodeType.CLOT)
    outside_free = max(float(fraction_outside_wall(jnp.asarray(f), clot_mask, guards.wall))
                       for f in free)
    outside_guarded = max(float(fraction_outside_wall(jnp.asarray(f), clot_mask, guards.wall))
                          for f in traj)
    assert outside_free > 0.5 and outside_guarded == 0.0
    assert set(corr) == {"containment"} and corr["containment"].shape == (12, len(x0))
    assert corr["containment"][:, 30:].max() == 0.0 and corr["containment"].max() > 0.0
    np.testing.assert_array_equal(traj[:, 30:], np.broadcast_to(x0[30:], traj[:, 30:].shape))
    # off: the same compiled path without guards equals the free rollout
    plain, none = rollout_with_corrections(Outward(), {}, stats, x0, x0, node_type, mask, 12)
    assert none == {} and np.array_equal(np.asarray(plain), free)


def test_a_new_tolerance_margin_or_stiffness_runs_the_same_compiled_rollout():
    """The guards' distances and factors are traced: rolling out again at another coherence
    tolerance, stiffness or containment margin compiles nothing new, and each value still
    reaches the program (a tighter tolerance keeps the clot nearer its rigid start)."""
    import dataclasses

    from wall_factory import Outward, straight_tube

    from thrombojax.eval.coherence_fit import clot_deviations
    from thrombojax.simulator.guard_set import build_guards
    from thrombojax.simulator.rollout import rollout_jit, rollout_with_corrections
    from thrombojax.types import TargetStats

    x0, node_type = straight_tube()
    mask = np.ones(len(x0), bool)
    stats = TargetStats(mean=jnp.zeros(3), std=jnp.ones(3))

    def run(**kw):
        """The largest correction of each guard, and the clot's largest distance from a rigid
        copy of its start (after a coherence guard of stiffness 1: about its tolerance; the
        correction moves the best rigid copy a little)."""
        guards = build_guards(x0, node_type, x0, node_type, radius=1.0, **kw)
        traj, corr = rollout_with_corrections(Outward(), {}, stats, x0, x0, node_type, mask, 8,
                                              guards=guards)
        frames = np.concatenate([x0[None], np.asarray(traj)])
        spread = float(clot_deviations(frames, node_type, 0, 1.0).max())
        return {"spread": spread} | {k: float(np.asarray(v).max()) for k, v in corr.items()}

    loose = run(tolerance_r=0.5, containment=False)
    size = rollout_jit._cache_size()
    tight = run(tolerance_r=0.05, containment=False)
    soft = run(tolerance_r=0.05, containment=False, stiffness=0.5)
    assert rollout_jit._cache_size() == size
    assert tight["spread"] < 0.08 < 0.3 < loose["spread"] < 0.6
    assert soft["spread"] > tight["spread"]
    contained = run(tolerance_r=0.05)
    size = rollout_jit._cache_size()
    margin = run(tolerance_r=0.05, margin_r=0.2)
    assert rollout_jit._cache_size() == size
    assert soft["coherence"] != tight["coherence"]
    assert margin["containment"] != contained["containment"]
    guards = build_guards(x0, node_type, x0, node_type, radius=1.0)
    assert dataclasses.replace(guards, tolerance=0.3).tolerance == 0.3
