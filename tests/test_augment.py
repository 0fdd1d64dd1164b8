"""Augmentations: rotation keeps geometry, subsampling keeps the clot fraction, BaryCentricSampling
puts points on triangles with constant coefficients, the generated ratio holds."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from dataset_factory import synthetic_window

from thrombojax.data.augment import (
    AugmentConfig,
    augment_batch,
    barycentric_resample,
    find_sample_triangles,
    random_rotation,
    rotate_window,
    subsample_indices,
)
from thrombojax.data.batching import Batch, epoch_plan
from thrombojax.errors import ConfigError
from thrombojax.graph.neighbors import radius_graph
from thrombojax.graph.triangles import find_triangles
from thrombojax.types import NodeType


def _window(seed=0):
    return synthetic_window(seed)


def _pairwise(x):
    return np.linalg.norm(x[:, None] - x[None], axis=-1)


def test_rotation_is_orthogonal_and_bounded():
    for i in range(20):
        rot = np.asarray(random_rotation(jax.random.PRNGKey(i), 0.3))
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-5)
        assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-5)
        angle = np.arccos(np.clip((np.trace(rot) - 1) / 2, -1, 1))
        assert angle <= 0.3 + 1e-4
    np.testing.assert_allclose(random_rotation(jax.random.PRNGKey(0), 0.0), np.eye(3), atol=1e-7)


def test_uniform_rotation_draws_every_orientation_alike():
    """``uniform=True``: the angle of the uniform measure on rotations, whose mean matrix is 0
    (E[trace R] = 0) and which turns by < 45 degrees 2.5 % of the time; the default uniform
    angle turns by < 45 degrees a quarter of the time and has E[trace R] = 1."""
    keys = jax.random.split(jax.random.PRNGKey(7), 4000)
    draw = jax.jit(jax.vmap(random_rotation, in_axes=(0, None, None)), static_argnums=2)
    haar, plain = np.asarray(draw(keys, np.pi, True)), np.asarray(draw(keys, np.pi, False))
    for rots in (haar, plain):
        np.testing.assert_allclose(rots @ np.swapaxes(rots, 1, 2),
                                   np.broadcast_to(np.eye(3), rots.shape), atol=1e-5)
        np.testing.assert_allclose(np.linalg.det(rots), 1.0, atol=1e-5)

    def angles(rots):
        return np.arccos(np.clip((np.trace(rots, axis1=1, axis2=2) - 1) / 2, -1, 1))

    assert abs(np.trace(haar, axis1=1, axis2=2).mean()) < 0.1
    assert abs(np.trace(plain, axis1=1, axis2=2).mean() - 1.0) < 0.1
    assert (angles(haar) < np.pi / 4).mean() == pytest.approx(0.025, abs=0.01)
    assert (angles(plain) < np.pi / 4).mean() == pytest.approx(0.25, abs=0.03)
    np.testing.assert_allclose(np.abs(haar.mean(axis=0)), 0.0, atol=0.05)  # E[R] = 0
    small = np.asarray(draw(keys[:200], 0.3, True))
    assert angles(small).max() <= 0.3 + 1e-4  # max_angle still bounds it


def test_rotated_window_keeps_distances_and_clot_mask():
    frames, node_type, mask = _window()
    batch = Batch(
        frames=jnp.asarray(frames)[None], node_type=jnp.asarray(node_type)[None],
        mask=jnp.asarray(mask)[None], generated=jnp.zeros((1,), bool),
    )
    out = augment_batch(jax.random.PRNGKey(3), batch, AugmentConfig(max_rotation=np.pi))
    rotated = np.asarray(out.frames[0])
    assert not np.allclose(rotated, frames, atol=1e-3)  # it did rotate
    for f in range(3):  # same rigid motion in every frame: pairwise distances unchanged
        np.testing.assert_allclose(_pairwise(rotated[f]), _pairwise(frames[f]), atol=2e-5)
    # one rotation for the whole window: displacements between frames rotate with it
    rot = np.linalg.lstsq(frames[1], rotated[1], rcond=None)[0].T
    np.testing.assert_allclose(rotated[2] - rotated[1], (frames[2] - frames[1]) @ rot.T, atol=2e-5)
    np.testing.assert_array_equal(np.asarray(out.node_type[0]), node_type)  # the mask follows
    np.testing.assert_array_equal(np.asarray(out.mask[0]), mask)
    np.testing.assert_array_equal(rotated[:, ~mask], 0.0)  # padding stays at the origin


def test_rotate_window_direct():
    frames, _, _ = _window()
    rot = random_rotation(jax.random.PRNGKey(1), np.pi)
    out = np.asarray(rotate_window(jnp.asarray(frames), rot))
    np.testing.assert_allclose(out[1] @ np.asarray(rot), frames[1], atol=1e-5)


def test_subsample_keeps_clot_fraction_and_is_seeded():
    node_type = np.array([NodeType.VESSEL] * 900 + [NodeType.CLOT] * 100, np.int8)
    idx = subsample_indices(np.random.default_rng(0), node_type, 200)
    assert idx.shape == (200,) and np.unique(idx).size == 200
    assert (node_type[idx] == NodeType.CLOT).sum() == 20
    again = subsample_indices(np.random.default_rng(0), node_type, 200)
    np.testing.assert_array_equal(idx, again)
    np.testing.assert_array_equal(subsample_indices(np.random.default_rng(0), node_type, 5000),
                                  np.arange(1000))
    with pytest.raises(ConfigError):
        subsample_indices(np.random.default_rng(0), node_type, 0)


def test_triangles_match_the_numpy_reference():
    frames, node_type, mask = _window()
    pos, m = jnp.asarray(frames[1]), jnp.asarray(mask)
    nbrs = radius_graph(pos, 0.35, 40, mask=m)
    assert int(nbrs.counts.max()) < 40  # uncapped: the reference sees the same edge set
    tri, valid = find_sample_triangles(pos, m, radius=0.35, max_neighbors=40)
    ours = {tuple(t) for t in np.asarray(tri)[np.asarray(valid)].tolist()}
    ref, count, _ = find_triangles(nbrs)
    assert len(ours) == int(valid.sum()) == count > 0  # each triangle once
    assert ours == {tuple(t) for t in np.asarray(ref)[:count].tolist()}
    capped, capped_valid = find_sample_triangles(pos, m, radius=0.35, max_neighbors=4)
    assert {tuple(t) for t in np.asarray(capped)[np.asarray(capped_valid)].tolist()} <= ours


def test_barycentric_points_lie_on_triangles_in_every_frame():
    frames, node_type, mask = _window()
    tri, ok = find_sample_triangles(
        jnp.asarray(frames[1]), jnp.asarray(mask), radius=0.35, max_neighbors=8
    )
    assert int(ok.sum()) > 0
    new, coef, verts = barycentric_resample(
        jax.random.PRNGKey(0), jnp.asarray(frames), jnp.asarray(node_type), jnp.asarray(mask),
        tri, ok,
    )
    new, coef, verts = np.asarray(new), np.asarray(coef), np.asarray(verts)
    real = np.flatnonzero(mask)
    assert np.all(coef >= 0) and np.allclose(coef.sum(1), 1.0, atol=1e-6)
    valid = {tuple(sorted(t)) for t in np.asarray(tri)[np.asarray(ok)].tolist()}
    for i in real:
        assert tuple(sorted(verts[i].tolist())) in valid  # a triangle of the edge set
        assert np.all(node_type[verts[i]] == node_type[i])  # of the point's own node type
        for f in range(3):  # same coefficients in all frames: the point moves with its triangle
            np.testing.assert_allclose(new[f, i], coef[i] @ frames[f, verts[i]], atol=1e-5)
        # recover the coefficients from each frame independently (least squares on the plane)
        for f in range(3):
            a = np.concatenate([frames[f, verts[i]].T, np.ones((1, 3))])
            b = np.concatenate([new[f, i], [1.0]])
            np.testing.assert_allclose(np.linalg.lstsq(a, b, rcond=None)[0], coef[i], atol=1e-3)
    assert not np.allclose(new[:, real], frames[:, real])  # new points, not copies
    np.testing.assert_array_equal(new[:, ~mask], frames[:, ~mask])
    vessel = real[node_type[real] == NodeType.VESSEL]
    np.testing.assert_allclose(new[0, vessel], new[2, vessel], atol=1e-6)  # vessel stays rigid


def test_generated_ratio_and_batch_replacement():
    plan = epoch_plan(30, bary_ratio=2.0, batch_size=8, seed=1, epoch=0).reshape(-1, 2)
    real = plan[(plan[:, 0] >= 0) & (plan[:, 1] == 0)]
    gen = plan[plan[:, 1] == 1]
    assert len(real) == 30 and len(gen) == 60  # real:generated = 1:2
    np.testing.assert_array_equal(np.sort(real[:, 0]), np.arange(30))
    assert not np.array_equal(plan, epoch_plan(30, bary_ratio=2.0, batch_size=8, seed=1,
                                               epoch=1).reshape(-1, 2))
    frames, node_type, mask = _window()
    batch = Batch(
        frames=jnp.stack([jnp.asarray(frames)] * 2), node_type=jnp.stack([node_type] * 2),
        mask=jnp.stack([mask] * 2), generated=jnp.array([False, True]),
    )
    cfg = AugmentConfig(max_rotation=0.0, barycentric=True, radius=0.35, max_neighbors=8)
    out = augment_batch(jax.random.PRNGKey(0), batch, cfg)
    np.testing.assert_array_equal(np.asarray(out.frames[0]), frames)  # real sample untouched
    assert not np.allclose(np.asarray(out.frames[1]), frames)
    np.testing.assert_array_equal(np.asarray(out.mask), np.asarray(batch.mask))


def test_uniform_rotation_reaches_the_batch_the_config_and_the_cli():
    from thrombojax.cli import build_parser
    from thrombojax.train.config import TrainConfig

    frames, node_type, mask = _window()
    batch = Batch(frames=np.asarray(frames)[None], node_type=np.asarray(node_type)[None],
                  mask=np.asarray(mask)[None], generated=np.zeros(1, bool))
    key = jax.random.PRNGKey(3)
    outs = {u: np.asarray(augment_batch(key, batch, AugmentConfig(uniform_rotation=u)).frames)
            for u in (False, True)}
    k_rot = jax.random.split(jax.random.split(key, 1)[0])[1]  # the sample's rotation key
    for u, out in outs.items():
        want = np.asarray(frames) @ np.asarray(random_rotation(k_rot, np.pi, u)).T
        np.testing.assert_allclose(out[0], want, atol=1e-5)
    assert not np.allclose(outs[False], outs[True])
    assert TrainConfig.from_dict({}).uniform_rotation is False  # older run configs
    assert TrainConfig(uniform_rotation=True).to_dict()["uniform_rotation"] is True
    with pytest.raises(ConfigError, match="uniform_rotation"):
        TrainConfig(uniform_rotation=1)
    args = build_parser().parse_args(["train", "--dataset", "d.h5", "--model", "mgn", "--out",
                                      "o", "--uniform-rotation"])
    assert args.uniform_rotation is True
