"""Tests of the model registry, the configs and the constant-velocity baseline."""

import dataclasses
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax import study
from thrombojax.errors import ConfigError
from thrombojax.models import (
    MODEL_NAMES,
    ConstantVelocity,
    ErwinConfig,
    MeshGraphNetConfig,
    TransolverConfig,
    config_from_dict,
    config_to_dict,
    count_params,
    create_model,
    get_config,
    identity_stats,
)
from thrombojax.simulator.step import make_step
from thrombojax.types import ModelInput, NodeType


def _inputs(n=24, n_pad=8, seed=0):
    k = jax.random.split(jax.random.key(seed), 3)
    pos = jax.random.uniform(k[0], (n + n_pad, 3), minval=-0.5, maxval=0.5)
    vel = 0.01 * jax.random.normal(k[1], (n + n_pad, 3))
    node_type = (jnp.arange(n + n_pad) % 2).astype(jnp.int32)
    return ModelInput(pos, vel, node_type, jnp.arange(n + n_pad) < n)


def test_names_and_aliases():
    for name in ("mgn", "transolver", "constant_velocity"):
        assert name in MODEL_NAMES
        assert create_model(name).name == name
    assert create_model("MeshGraphNet").name == "mgn"


def test_unknown_model_lists_known_ones():
    with pytest.raises(ConfigError, match="unknown model 'gcn'.*mgn.*transolver"):
        create_model("gcn")
    with pytest.raises(ConfigError, match="unknown model"):
        get_config("gcn")


def test_wrong_config_type_rejected():
    with pytest.raises(ConfigError, match="MeshGraphNetConfig"):
        create_model("mgn", TransolverConfig())


def test_study_defaults():
    mgn = get_config("mgn")
    assert (mgn.hidden, mgn.processor_size, mgn.radius, mgn.max_neighbors) == (64, 15, 0.56, 32)
    assert study.training_defaults("mgn") == {"batch_size": 8, "lr": 1e-3}
    e = ErwinConfig()
    assert (e.hidden, e.mlp_ratio, e.rotate, e.radius) == (32, 4, 45.0, 0.766)
    assert study.training_defaults("erwin") == {"batch_size": 8, "lr": 1e-4}
    assert e.enc_heads == (4, 4, 4, 4) and e.enc_depths == (8, 10, 12, 14)
    assert e.dec_heads == (4, 4, 4) and e.dec_depths == (4, 4, 4)
    assert e.strides == (2, 2, 2) and e.ball_sizes == (128, 128, 128, 128)
    for cls in (MeshGraphNetConfig, TransolverConfig, ErwinConfig):
        assert cls().max_neighbors == 32 and cls.tiny() != cls()


def test_overrides_and_unknown_fields():
    cfg = get_config("transolver", tiny=True, dropout=0.0, slices=3)
    assert (cfg.dropout, cfg.slices, cfg.hidden) == (0.0, 3, TransolverConfig.tiny().hidden)
    with pytest.raises(ConfigError, match="unknown config field.*'hiden'"):
        get_config("mgn", hiden=3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.hidden = 3


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_config_dict_round_trip_through_json(name):
    cfg = get_config(name, tiny=True)
    d = json.loads(json.dumps(config_to_dict(cfg)))
    assert config_from_dict(name, d) == cfg
    with pytest.raises(ConfigError, match="unknown config field"):
        config_from_dict(name, {**d, "bogus": 1})


def test_erwin_config_sequences_become_tuples():
    d = json.loads(json.dumps(config_to_dict(ErwinConfig())))
    assert d["ball_sizes"] == [128, 128, 128, 128]
    cfg = ErwinConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})
    assert cfg == ErwinConfig() and hash(cfg) == hash(ErwinConfig())


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_every_registered_model_follows_the_contract(name):
    """build_graph / init / apply trace as one function (jittable): [N, 3] float32 output.

    Traced abstractly (``jax.eval_shape``, no compilation) to stay fast; the numerical
    acceptance tests live in each model's test file.
    """
    model = create_model(name, get_config(name, tiny=True))
    assert hash(model) == hash(create_model(name, get_config(name, tiny=True)))
    inputs = _inputs()

    def run(rng):
        graph = model.build_graph(inputs)
        params = model.init(rng, inputs, graph)
        out = model.apply(params, inputs, graph)
        return out, params

    out, params = jax.eval_shape(run, jax.random.key(0))
    assert out.shape == (inputs.n_nodes, 3) and out.dtype == jnp.float32
    assert (count_params(params) == 0) == (name == "constant_velocity")


def test_constant_velocity_integrates_to_x_plus_v():
    model = create_model("constant_velocity")
    assert isinstance(model, ConstantVelocity)
    inputs = _inputs(n=10, n_pad=2)
    x_cur = inputs.positions
    x_prev = x_cur - inputs.velocity
    assert model.init(jax.random.key(0), inputs, model.build_graph(inputs)) == {}
    res = make_step(model)({}, identity_stats(), x_prev, x_cur, inputs.node_type, inputs.mask)
    x_next, out = res.positions, res.output
    np.testing.assert_array_equal(out, 0.0)
    clot = np.asarray(inputs.mask & (inputs.node_type == NodeType.CLOT))
    np.testing.assert_allclose(x_next[clot], (x_cur + (x_cur - x_prev))[clot], atol=1e-7)
    np.testing.assert_array_equal(x_next[~clot], x_cur[~clot])


def test_count_params():
    assert count_params({"a": jnp.zeros((2, 3)), "b": [jnp.zeros(4)]}) == 10


@pytest.mark.parametrize(
    ("name", "bad"),
    [
        ("mgn", {"hidden": 0}),
        ("mgn", {"radius": -1.0}),
        ("transolver", {"heads": 3}),
        ("transolver", {"dropout": 1.0}),
        ("transolver", {"max_neighbors": 0}),
    ],
)
def test_invalid_configs_rejected(name, bad):
    with pytest.raises(ConfigError):
        get_config(name, **bad)
