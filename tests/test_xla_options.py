"""The CPU compiler options of thrombojax's compiled paths (issue 17): chosen, applied, safe.

The options change which library XLA multiplies with, not what is computed: the training step
and the rollout give the same results as ``jax.jit`` with XLA's defaults, to 1e-5.
"""

import jax
import numpy as np
import pytest
from dataset_factory import rollout_state, synthetic_window, window_batch
from tree_helpers import assert_trees_close

from thrombojax import xla_options
from thrombojax.models.registry import create_model, get_config
from thrombojax.simulator.rollout import _rollout_impl, rollout_jit
from thrombojax.simulator.step import make_step
from thrombojax.train.schedule import make_optimizer, make_schedule
from thrombojax.train.step import init_state, make_eval_step, make_train_step
from thrombojax.types import TargetStats

YNN = "xla_cpu_experimental_ynn_fusion_type"


@pytest.fixture
def fresh_options():
    """Clear the per-process choice before and after (it is cached)."""
    xla_options.cpu_compiler_options.cache_clear()
    yield
    xla_options.cpu_compiler_options.cache_clear()


def test_wanted_respects_opt_out_and_user_flags():
    options = {YNN: "", "xla_cpu_other": "1"}
    assert xla_options._wanted({}, options) == options
    assert xla_options._wanted({xla_options.OPT_OUT: "0"}, options) == {}
    assert xla_options._wanted({xla_options.OPT_OUT: "1"}, options) == options
    user = {"XLA_FLAGS": f"--xla_backend_optimization_level=1 --{YNN}=LIBRARY_FUSION_TYPE_DOT"}
    assert xla_options._wanted(user, options) == {"xla_cpu_other": "1"}


def test_cpu_gets_the_options_of_the_model(fresh_options, monkeypatch):
    monkeypatch.delenv(xla_options.OPT_OUT, raising=False)
    assert jax.default_backend() == "cpu"
    assert xla_options.cpu_compiler_options("mgn") == {YNN: ""}
    assert xla_options.cpu_compiler_options("mgn", train=True) == {YNN: ""}
    for other in ("transolver", "erwin", "constant_velocity", None):
        assert xla_options.cpu_compiler_options(other) == {}
    assert xla_options.cpu_compiler_options("erwin", train=True) == {YNN: ""}  # training only
    assert xla_options.cpu_compiler_options("transolver", train=True) == {}
    monkeypatch.setenv(xla_options.OPT_OUT, "0")
    xla_options.cpu_compiler_options.cache_clear()
    assert xla_options.cpu_compiler_options("mgn") == {}


def test_unknown_option_warns_and_falls_back(fresh_options, monkeypatch):
    monkeypatch.delenv(xla_options.OPT_OUT, raising=False)
    monkeypatch.setattr(xla_options, "MODEL_CPU_OPTIONS",
                        {"mgn": {"xla_cpu_no_such_option_here": "1"}})
    with pytest.warns(RuntimeWarning, match="xla_cpu_no_such_option_here"):
        assert xla_options.cpu_compiler_options("mgn") == {}
    f = xla_options.jit(lambda x: 2 * x, model="mgn")  # still compiles, with XLA's defaults
    assert float(f(3.0)) == 6.0


def test_jit_wrapper_is_jax_jit(fresh_options):
    @xla_options.jit
    def f(x, n):
        return x * n

    @xla_options.jit(static_argnames=("n",))
    def g(x, n):
        return x * n

    assert f.__name__ == "f" and f.__wrapped__(2.0, 3) == 6.0 and float(f(2.0, 3)) == 6.0
    assert float(g(2.0, n=4)) == 8.0 and float(g(1.0, n=4)) == 4.0 and g._cache_size() == 1
    assert "mul" in g.lower(1.0, n=2).as_text()


def test_the_model_is_read_from_the_step_argument(fresh_options):
    mgn, transolver = (create_model(m, get_config(m, tiny=True)) for m in ("mgn", "transolver"))
    assert xla_options.step_model_name(make_step(mgn), 1.0) == "mgn"
    assert xla_options.step_model_name(1.0, step=make_step(transolver)) == "transolver"
    assert xla_options.step_model_name() is None and xla_options.step_model_name(3.0) is None

    @xla_options.jit(model_of=xla_options.step_model_name, static_argnums=0)
    def h(step, x):
        return x + 1.0

    assert float(h(make_step(mgn), 1.0)) == 2.0 and float(h(make_step(transolver), 1.0)) == 2.0
    assert len(h._jitted) == 2 and h._cache_size() == 2  # one jax.jit per option set


def _tiny(name="mgn"):
    return create_model(name, get_config(name, tiny=True, radius=0.5, hidden=16))


def _ynn_in(compiled_text: str) -> bool:
    return "ynn_fusion" in compiled_text


def _train_steps(model, tx):
    """``(state, data, key, stats, fast, plain)``: a two-window batch, the initial state, and
    the training step compiled by :func:`make_train_step` and by ``jax.jit`` with XLA's
    defaults."""
    batch = window_batch([synthetic_window(s, n_clot=20, n_pad=4) for s in range(2)])
    state = init_state(model, tx, jax.random.PRNGKey(0), batch)
    stats = TargetStats(mean=jax.numpy.zeros(3), std=jax.numpy.full(3, 1e-2))
    fast = make_train_step(model, tx, stats, donate=False)
    data, key = jax.tree.map(jax.numpy.asarray, batch), jax.random.PRNGKey(1)
    return state, data, key, stats, fast, jax.jit(fast.__wrapped__)


def test_train_step_equals_the_default_compilation(fresh_options):
    state, data, key, _, fast, plain = _train_steps(
        _tiny(), make_optimizer(make_schedule(1e-3, 100, 2)))
    # the options reach the compiler: no YNNPACK fusion in the optimised program
    assert _ynn_in(plain.lower(state, data, key).compile().as_text())
    assert not _ynn_in(fast.lower(state, data, key).compile().as_text())
    s_fast, s_plain = state, state
    for i in range(3):
        s_fast, m_fast = fast(s_fast, data, jax.random.PRNGKey(i))
        s_plain, m_plain = plain(s_plain, data, jax.random.PRNGKey(i))
        assert_trees_close(m_fast, m_plain)
    assert_trees_close(s_fast.params, s_plain.params)


def test_erwin_gets_the_options_in_its_training_step_only(fresh_options):
    """Erwin's training step compiles without YNNPACK and equals XLA's defaults; its evaluation
    step (forward only, like its rollouts) keeps them."""
    # one block per level (no scanned pair): the options, not the depth, are under test
    model = create_model("erwin", get_config("erwin", tiny=True, radius=0.5, enc_depths=(1, 1),
                                             dec_depths=(1,)))
    state, data, key, stats, fast, plain = _train_steps(model, make_optimizer(1e-3))
    assert _ynn_in(plain.lower(state, data, key).compile().as_text())
    assert not _ynn_in(fast.lower(state, data, key).compile().as_text())
    s_fast, m_fast = fast(state, data, key)
    s_plain, m_plain = plain(state, data, key)
    assert_trees_close(m_fast, m_plain)
    assert_trees_close(s_fast.params, s_plain.params)
    evaluate = make_eval_step(model, stats)
    assert _ynn_in(evaluate.lower(state.params, data).compile().as_text())


def test_rollout_equals_the_default_compilation(fresh_options):
    model = _tiny()
    x_prev, x_cur, node_type, mask, stats = rollout_state(40, seed=3)
    step = make_step(model)
    params = step.init(jax.random.key(0), x_prev, x_cur, node_type, mask)
    plain = jax.jit(_rollout_impl, static_argnames=("step", "n_steps"))
    args = (params, stats, x_prev, x_cur, node_type, mask)
    assert _ynn_in(plain.lower(step, *args, n_steps=4).compile().as_text())
    assert not _ynn_in(rollout_jit.lower(step, *args, n_steps=4).compile().as_text())
    fast_traj = np.asarray(rollout_jit(step, *args, 4)[0])
    plain_traj = np.asarray(plain(step, *args, 4)[0])
    np.testing.assert_allclose(fast_traj, plain_traj, rtol=1e-5, atol=1e-5)


def test_models_without_options_compile_with_the_defaults(fresh_options):
    step = make_step(_tiny("transolver"))
    x_prev, x_cur, node_type, mask, stats = rollout_state(40, seed=3)
    params = step.init(jax.random.key(0), x_prev, x_cur, node_type, mask)
    args = (params, stats, x_prev, x_cur, node_type, mask)
    assert _ynn_in(rollout_jit.lower(step, *args, n_steps=2).compile().as_text())


def test_a_rollout_inside_another_jit_compiles_with_the_outer_options(fresh_options):
    # jax refuses compiler_options on a nested jit (benchmarks/step_inputs.py jits a rollout)
    model = _tiny()
    x_prev, x_cur, node_type, mask, stats = rollout_state(40, seed=4)
    step = make_step(model)
    params = step.init(jax.random.key(0), x_prev, x_cur, node_type, mask)

    @xla_options.jit(model="mgn")
    def outer(params, x_prev, x_cur):
        return rollout_jit(step, params, stats, x_prev, x_cur, node_type, mask, 3)[0]

    nested = np.asarray(outer(params, x_prev, x_cur))
    alone = np.asarray(rollout_jit(step, params, stats, x_prev, x_cur, node_type, mask, 3)[0])
    np.testing.assert_allclose(nested, alone, rtol=1e-5, atol=1e-5)
    assert not _ynn_in(outer.lower(params, x_prev, x_cur).compile().as_text())
