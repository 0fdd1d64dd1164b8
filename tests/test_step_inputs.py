"""Inputs that generalise: the vessel frame (rotation invariance) and the wall features."""

import json

import jax
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.errors import ConfigError
from thrombojax.graph.frame import vessel_frame
from thrombojax.graph.wall_nodes import (
    WALL_NORMAL_NODES,
    local_wall_plane,
    nearest_vessel_node,
    pairwise_sq_distances,
    tie_key,
    wall_node_features,
    wall_patches,
)
from thrombojax.io.hdf5 import open_dataset
from thrombojax.models.registry import create_model, get_config, identity_stats
from thrombojax.simulator.step import make_step, target_acceleration
from thrombojax.types import NodeType, TargetStats

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)
SHIFT = np.array([0.3, -0.2, 0.1], np.float32)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """Three frames of a tiny-preset BendVessel simulation, scaled to about [-1, 1]."""
    from thrombojax.sim.generate import generate_dataset

    path = tmp_path_factory.mktemp("bend") / "bend.h5"
    generate_dataset("bendvessel-tiny", path, n_sims=1, seed=3, progress=False)
    ds = open_dataset(path)
    name = ds.names[0]
    pos = np.asarray(ds.positions(name), np.float32)
    scale = np.abs(pos).max()
    return pos[4:7] / scale, np.asarray(ds.node_type(name))


def _moved(x):
    return x @ ROT.T + SHIFT


def test_vessel_frame_moves_with_the_vessel(frames):
    pos, nt = frames
    f, g = vessel_frame(pos[0], nt), vessel_frame(_moved(pos[0]), nt)
    axes = np.asarray(f.axes)
    assert np.allclose(axes.T @ axes, np.eye(3), atol=1e-5)
    assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-5)
    np.testing.assert_allclose(np.asarray(g.points(_moved(pos[1]))),
                               np.asarray(f.points(pos[1])), atol=2e-5)
    vec = pos[1] - pos[0]
    np.testing.assert_allclose(np.asarray(f.vectors_to_global(f.vectors(vec))), vec, atol=1e-6)


def test_frame_without_vessel_nodes_is_the_identity():
    x = np.random.default_rng(0).normal(size=(5, 3)).astype(np.float32)
    f = vessel_frame(x, np.full(5, NodeType.CLOT))
    np.testing.assert_allclose(np.asarray(f.axes), np.eye(3))


@pytest.mark.parametrize("frame, invariant", [("vessel", True), ("global", False)])
def test_a_vessel_frame_step_is_invariant_to_rotation(frames, frame, invariant):
    """Rotating and shifting the inputs rotates and shifts the vessel-frame step's output
    (an orientation never seen before gives the same answer); the global step is not."""
    pos, nt = frames
    mask = np.ones(len(nt), bool)
    step = make_step(create_model("mgn", get_config("mgn", tiny=True)), frame)
    params = step.init(jax.random.key(0), pos[0], pos[1], nt, mask)
    stats = TargetStats(mean=np.full(3, 1e-3, np.float32), std=np.full(3, 0.01, np.float32),
                        velocity_std=np.float32(0.01))
    a = np.asarray(step(params, stats, pos[0], pos[1], nt, mask).positions)
    b = np.asarray(step(params, stats, _moved(pos[0]), _moved(pos[1]), nt, mask).positions)
    moved = float(np.abs(_moved(a) - _moved(pos[1])).max())  # size of one step
    err = float(np.abs(_moved(a) - b).max())
    assert (err < 1e-3 * max(moved, 1e-3)) == invariant, (err, moved)


def test_normalized_target_is_what_the_step_integrates(frames):
    """An output equal to the normalised target lands exactly on the true next frame."""
    pos, nt = frames
    mask = np.ones(len(nt), bool)
    step = make_step(create_model("constant_velocity"), "vessel")
    stats = TargetStats(mean=np.array([1e-3, 0, -1e-3], np.float32),
                        std=np.array([0.02, 0.01, 0.03], np.float32),
                        velocity_std=np.float32(0.01))
    target = step.normalized_target(stats, target_acceleration(pos[0], pos[1], pos[2]), pos[1],
                                    nt, mask)
    frame = step.frame_of(pos[1], nt, mask)
    accel = np.asarray(frame.vectors_to_global(stats.denormalize(target)))
    clot = nt == NodeType.CLOT
    np.testing.assert_allclose((2 * pos[1] - pos[0] + accel)[clot], pos[2][clot], atol=1e-5)


def test_wall_node_features_measure_the_nearest_vessel_node():
    vessel = np.array([[0, 0, 0], [2, 0, 0], [0, 3, 0]], np.float32)
    clot = np.array([[0.5, 0, 0], [1.6, 0, 0], [0, 5, 0]], np.float32)
    x = np.concatenate([vessel, clot, [[9, 9, 9]]])
    nt = np.array([0, 0, 0, 1, 1, 1, 1], np.int32)
    mask = np.array([True] * 6 + [False])
    f = np.asarray(wall_node_features(x, nt, mask, cutoff=1.0))
    np.testing.assert_allclose(f[3], [0.5, -1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(f[4], [0.4, 1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(f[5], [1.0, 0, 0, 0], atol=1e-6)  # beyond the cutoff
    assert not f[:3].any() and not f[6].any()  # vessel and padded nodes get zeros
    with pytest.raises(ValueError, match="cutoff"):
        wall_node_features(x, nt, mask, cutoff=0.0)


def test_nearest_vessel_node_blocks_agree_with_one_pass():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(300, 3)).astype(np.float32)
    nt = (rng.random(300) < 0.4).astype(np.int32)
    mask = rng.random(300) < 0.9
    one = np.asarray(nearest_vessel_node(x, nt, mask, block=1024))
    blocks = np.asarray(nearest_vessel_node(x, nt, mask, block=64))
    np.testing.assert_array_equal(one, blocks)
    vessel = np.flatnonzero(mask & (nt == 0))
    d = np.linalg.norm(x[:, None] - x[None, vessel], axis=-1)
    np.testing.assert_array_equal(one, vessel[d.argmin(1)])


def test_wall_features_reach_the_model(frames):
    """With wall features the step's output depends on where the wall is, also for a clot
    node with no vessel node among its graph neighbours; the parameters grow by the 4 inputs."""
    pos, nt = frames
    mask = np.ones(len(nt), bool)
    model = create_model("mgn", get_config("mgn", tiny=True, max_neighbors=4))
    plain, walled = make_step(model), make_step(model, wall_cutoff=0.5)
    p0 = plain.init(jax.random.key(0), pos[0], pos[1], nt, mask)
    p1 = walled.init(jax.random.key(0), pos[0], pos[1], nt, mask)
    k0 = p0["params"]["node_encoder"]["dense_0"]["kernel"]
    k1 = p1["params"]["node_encoder"]["dense_0"]["kernel"]
    assert k1.shape[0] == k0.shape[0] + 4
    stats = identity_stats()
    inputs = walled.inputs(stats, pos[0], pos[1], nt, mask)
    clot = nt == NodeType.CLOT
    assert np.asarray(inputs.extra)[clot, 0].min() < 1.0  # some clot nodes feel the wall
    assert plain.inputs(stats, pos[0], pos[1], nt, mask).extra is None
    with pytest.raises(ConfigError, match="wall_cutoff"):
        make_step(model, wall_cutoff=-1.0)
    with pytest.raises(ConfigError, match="frame"):
        make_step(model, "sideways")


def test_clot_wall_mean_gives_every_clot_node_the_clot_wide_room(frames):
    """``wall_clot_mean``: one more input column, on every real clot node the mean of the clot's
    clipped wall distances (padded and vessel nodes 0); it grows when the vessel is wider about
    the clot, where each node alone sees only its own distance; it needs the wall features."""
    pos, nt = frames
    mask = np.ones(len(nt), bool)
    clot = nt == NodeType.CLOT
    mask[np.flatnonzero(clot)[-3:]] = False  # three padded clot nodes do not count
    real = clot & mask
    model = create_model("mgn", get_config("mgn", tiny=True, max_neighbors=4))
    walled = make_step(model, wall_cutoff=0.5)
    room = make_step(model, wall_cutoff=0.5, wall_clot_mean=True)
    stats = identity_stats()

    def extra(step, x):
        return np.asarray(step.inputs(stats, x, x, nt, mask).extra)

    plain, with_room = extra(walled, pos[1]), extra(room, pos[1])
    assert with_room.shape[1] == plain.shape[1] + 1
    np.testing.assert_array_equal(with_room[:, :-1], plain)
    np.testing.assert_allclose(with_room[real, -1], plain[real, 0].mean(), rtol=1e-6)
    assert np.all(with_room[~real, -1] == 0.0)
    # the vessel 20 % wider about the clot's centroid: the clot has more room
    centre = pos[1][real].mean(0)
    wide = np.where(clot[:, None], pos[1], centre + 1.2 * (pos[1] - centre))
    assert extra(room, wide)[real, -1].mean() > with_room[real, -1].mean()
    p0 = walled.init(jax.random.key(0), pos[0], pos[1], nt, mask)
    p1 = room.init(jax.random.key(0), pos[0], pos[1], nt, mask)
    assert (p1["params"]["node_encoder"]["dense_0"]["kernel"].shape[0]
            == p0["params"]["node_encoder"]["dense_0"]["kernel"].shape[0] + 1)
    with pytest.raises(ConfigError, match="wall_clot_mean"):
        make_step(model, wall_clot_mean=True)
    from thrombojax.train.config import TrainConfig

    with pytest.raises(ConfigError, match="wall-clot-mean"):
        TrainConfig(wall_clot_mean=True)
    with pytest.raises(ConfigError, match="wall_clot_mean"):
        TrainConfig(wall_features=0.5, wall_clot_mean=1)


def test_recipes():
    from thrombojax.train.config import TrainConfig
    from thrombojax.train.recipes import DEFAULT_RECIPE, recipe

    assert DEFAULT_RECIPE == "outlet" and recipe("study") == {}
    assert {k: v for k, v in recipe("axis").items() if k not in recipe("history")} == {
        "axis_features": 2.0}
    assert all(recipe("axis")[k] == v for k, v in recipe("history").items())
    cfg = TrainConfig(**recipe("rollout"))
    assert cfg.rollout_steps > 1 and cfg.pushforward_steps > 0 and cfg.noise_std > 0
    cfg = TrainConfig(**recipe("history"))
    assert cfg.history == 2 and cfg.noise_walk and cfg.noise_std > 0 and cfg.rollout_steps == 1
    cfg = TrainConfig(**recipe("robust"))
    assert {k: v for k, v in recipe("robust").items() if k not in recipe("history")} == {
        "wall_noise": 0.1, "wall_features": 0.5, "wall_signed": True, "history_noise": 0.02,
        "speed_noise": 0.1, "direction_noise": 0.1, "select_by": "last"}
    assert all(getattr(cfg, k) == v for k, v in recipe("history").items())
    cfg = TrainConfig(**recipe("room"))
    assert {k: v for k, v in recipe("room").items() if recipe("axis").get(k) != v} == {
        "history": 1, "follow_axis": 2.0, "wall_features": 0.5, "wall_clot_mean": True,
        "clot_mean_weight": 10.0, "speed_noise": 0.3, "select_by": "last"}
    assert cfg.history == 1 and cfg.wall_clot_mean and cfg.follow_axis == 2.0
    assert {k: v for k, v in recipe("outlet").items() if recipe("room").get(k) != v} == {
        "outlet_features": 2.0}
    assert TrainConfig(**recipe("outlet")).outlet_features == 2.0
    with pytest.raises(ConfigError, match="unknown recipe"):
        recipe("fast")


def test_cli_offers_every_recipe():
    """`thrombojax train --recipe` lists its choices literally (the CLI does not import jax to
    build its parser): they must be the names of RECIPES, so each one is accepted."""
    from thrombojax.cli import build_parser
    from thrombojax.train.recipes import RECIPES

    train = next(a for a in build_parser()._subparsers._group_actions[0].choices["train"]._actions
                 if "--recipe" in a.option_strings)
    assert set(train.choices) == set(RECIPES)


def test_cli_trains_with_the_default_recipe_and_reloads_the_step(tmp_path):
    """`thrombojax train` without --config uses the default (outlet) recipe, options given on
    the command line above it; the run records the frame and the wall cutoff; the loaded
    model steps as it trained (the recipe's prior and history included, and the centring
    pull given on the command line with its tolerance fitted); a rollout runs through it."""
    from dataset_factory import train_tiny_cli

    from thrombojax.eval.report import rollout_run
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--wall-features", "2", "--wall-clot-mean", "--frame",
                               "vessel", "--centre-pull", "0.5", "--centre-tolerance", "auto",
                               n_nodes=80)
    loaded = load_trained(run)
    cfg = loaded.run.train
    assert (cfg.frame, cfg.history, cfg.noise_walk, cfg.rollout_steps) == ("vessel", 1, True, 1)
    assert (cfg.follow_axis, cfg.speed_noise, cfg.clot_mean_weight, cfg.select_by) == (
        2.0, 0.3, 10.0, "last")
    assert cfg.wall_features == 2.0  # the command line's, over the recipe's 0.5
    assert loaded.step.frame == "vessel" and loaded.step.history == 1
    assert loaded.step.prior_radius == pytest.approx(loaded.config["prior_radius"])
    assert loaded.step.prior_radius > 0  # the recipe's vessel-following prior
    assert loaded.step.wall_cutoff == pytest.approx(loaded.config["wall_cutoff"])
    assert loaded.step.wall_cutoff > 0 and loaded.step.wall_clot_mean and cfg.wall_clot_mean
    assert loaded.run.train.axis_features == 2.0 and loaded.step.axis_radius > 0  # the default
    assert cfg.outlet_features == 2.0 and loaded.step.outlet_radius > 0  # the default's outlet
    assert loaded.step.outlet_radius == pytest.approx(loaded.config["outlet_radius"])
    # the centring pull: a vessel radius is half the prior's width of 2 radii
    assert (cfg.centre_pull, loaded.step.centre_pull) == (0.5, 0.5)
    assert loaded.step.centre_unit == pytest.approx(loaded.step.prior_radius / 2)
    fit = loaded.config["centre_tolerance_fit"]  # auto: fitted on the training simulations
    assert fit["simulations"] == list(loaded.split.train) and fit["frames"] > 0
    assert loaded.step.centre_tolerance == pytest.approx(
        fit["centre_tolerance_r"] * loaded.step.centre_unit)
    report = rollout_run(run, data, tmp_path / "rollout", progress=False, gif=False)
    sims = report["simulations"]
    assert sims and all("NaN" not in json.dumps(r["summary"]) for r in sims.values())
    assert all(r["n_steps"] > 0 for r in sims.values())
    assert report["centre_pull"] == {"at": "training", "strength": 0.5, "fit": None,
                                     "tolerance_r": pytest.approx(fit["centre_tolerance_r"])}
    # the pull set at rollout time instead (thrombojax.eval.rollout_pull), from the CLI
    from thrombojax.cli import main

    out = tmp_path / "pulled"
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--centre-pull", "1", "--centre-tolerance", "0", "--no-gif", "--quiet"]) == 0
    pulled = json.loads((out / "rollout.json").read_text())
    assert pulled["centre_pull"] == {"at": "rollout", "strength": 1.0, "tolerance_r": 0.0,
                                     "fit": None}
    assert "Centring pull of the vessel-following prior (set at rollout)" in (
        out / "rollout.md").read_text()
    name = next(iter(sims))
    model = loaded.model.name
    assert (pulled["simulations"][name]["summary"][model]["mse@full"]
            != sims[name]["summary"][model]["mse@full"])  # the stronger pull moved the clot


def _differing(patch_a, patch_b) -> int:
    """Rows of two wall searches that hold different sets of nodes."""
    rows = zip(np.asarray(patch_a).tolist(), np.asarray(patch_b).tolist(), strict=True)
    return sum(set(a) != set(b) for a, b in rows)


def test_wall_search_picks_the_same_nodes_in_every_orientation(frames):
    """A tube's wall has rings of vessel nodes at equal distances: ranked by the raw squared
    distances, rounding in turned coordinates picks other nearest nodes (and other wall
    normals); ranked by tie_key, the same nodes, so the wall normals turn with the vessel."""
    pos, nt = frames
    x, mask = pos[1], np.ones(len(nt), bool)
    vessel = nt == NodeType.VESSEL

    def plain(y):  # the search before tie_key
        ranked = np.where(vessel[None, :], -np.asarray(pairwise_sq_distances(y)), -np.inf)
        return jax.lax.top_k(ranked, WALL_NORMAL_NODES)[1]

    turned = []
    for rot in Rotation.random(4, random_state=0).as_matrix().astype(np.float32):
        y = x @ rot.T + SHIFT
        before = _differing(plain(x), plain(y))
        after = _differing(wall_patches(x, nt, mask), wall_patches(y, nt, mask))
        turned.append((before, after))
        _, n0 = local_wall_plane(x, nt, mask)
        _, n1 = local_wall_plane(y, nt, mask)
        dots = np.abs(np.sum((np.asarray(n0) @ rot.T) * np.asarray(n1), axis=-1))[vessel]
        assert dots.min() > 0.999, dots.min()  # every vessel normal turned with the vessel
    assert all(after == 0 for _, after in turned), turned
    assert sum(before for before, _ in turned) > 0, turned  # the tiny tube has such ties


def test_tie_key_orders_like_the_distances_and_merges_rounding():
    sq = np.array([0.0, 1e-6, 0.25, 0.25 * (1 + 1e-6), 0.2505, 1.0, 4.0], np.float32)
    key = np.asarray(tie_key(sq))
    assert np.all(np.diff(key[[0, 1, 2, 4, 5, 6]]) > 0)  # distinct distances keep their order
    assert key[2] == key[3]  # a rounding-level difference is a tie
    assert np.all(key < 2**18) and np.all(key == np.round(key))
