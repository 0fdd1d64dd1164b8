"""Weight averaging (``--average-weights SHARE``): the model is the mean of the weights after each
of the last steps of the training (stochastic weight averaging over the tail of the cosine decay);
the optimiser's own weights, and so the training, are those of the same run without it; the
checkpoint holds the mean for every consumer and the iterate for an exact resume."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.train.averaging import average_weights
from thrombojax.train.config import TrainConfig


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree.leaves(tree)]


def test_the_running_mean_is_the_mean_of_the_tail():
    rng = np.random.default_rng(0)
    seq = [{"w": rng.normal(size=(3, 2)).astype(np.float32), "b": rng.normal(size=4)
            .astype(np.float32)} for _ in range(9)]
    average_from = 5  # steps done before the first averaged one: steps 6..9 are averaged
    avg = jax.tree.map(jnp.asarray, seq[0])
    for done, params in enumerate(seq[1:], start=2):  # the state after step 1 is seq[0]
        avg = average_weights(avg, params, jnp.int32(done), average_from)
        if done <= average_from + 1:  # before the tail, and its first step: the weights
            np.testing.assert_array_equal(np.asarray(avg["w"]), params["w"])
    want = {k: np.mean([s[k] for s in seq[5:]], axis=0) for k in ("w", "b")}
    for k in want:
        np.testing.assert_allclose(np.asarray(avg[k]), want[k], rtol=1e-6, atol=1e-6)


def test_the_share_is_checked():
    assert TrainConfig(average_weights=0.5).average_weights == 0.5
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ConfigError, match="average_weights"):
            TrainConfig(average_weights=bad)


@pytest.mark.slow
def test_the_model_is_the_mean_of_the_last_steps_and_resumes_exactly(tmp_path):
    from dataset_factory import tiny_cli_dataset

    from thrombojax.train.loop import train
    from thrombojax.train.state import load_trained, restore_checkpoint

    data = tiny_cli_dataset(tmp_path)
    kw = dict(tiny=True, epochs=2, batch_size=2, n_val=1, n_test=1, warmup_epochs=0.5,
              lr=3e-3, progress=False)

    # the same training without averaging: its weights after every step
    plain = tmp_path / "plain"
    seen = []
    train(data, "mgn", plain, **kw, checkpoint_every=1,
          callback=lambda step, _: seen.append(
              restore_checkpoint(plain / "checkpoints" / "last")[0]))
    total = len(seen)
    tail = total - round(0.5 * total)

    avg_dir = tmp_path / "avg"
    train(data, "mgn", avg_dir, average_weights=0.5, **kw)
    model = load_trained(avg_dir, which="last")
    want = [np.mean([_leaves(p)[i] for p in seen[tail:]], axis=0)
            for i in range(len(_leaves(seen[0])))]
    for got, ref in zip(_leaves(model.params), want, strict=True):
        np.testing.assert_allclose(got, ref, rtol=1e-5, atol=1e-6)
    # averaging does not change the training: the optimiser's weights are the plain run's
    iterate = _iterate(avg_dir)
    for got, ref in zip(_leaves(iterate), _leaves(seen[-1]), strict=True):
        np.testing.assert_array_equal(got, ref)
    # and the mean is a different model from the last weights
    assert max(float(np.abs(a - b).max())
               for a, b in zip(_leaves(model.params), _leaves(seen[-1]), strict=True)) > 1e-6

    # killed inside the averaged tail, resumed: the same mean, bit for bit
    cut = tail + 2
    resumed = tmp_path / "resumed"

    def stop(step, _):
        if step == cut:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        train(data, "mgn", resumed, average_weights=0.5, **kw, checkpoint_every=cut,
              callback=stop)
    train(data, "mgn", resumed, resume=True, progress=False)
    again = load_trained(resumed, which="last")
    for got, ref in zip(_leaves(again.params), _leaves(model.params), strict=True):
        np.testing.assert_array_equal(got, ref)


def _iterate(run_dir):
    """The optimiser's own weights stored in a run's last checkpoint (weight averaging on)."""
    import orbax.checkpoint as ocp

    from thrombojax.train.state import _manager, latest_step

    ckpt = run_dir / "checkpoints" / "last"
    with _manager(ckpt, read_only=True) as mngr:
        out = mngr.restore(latest_step(ckpt), args=ocp.args.Composite(
            train=ocp.args.StandardRestore()))
    return jax.tree.map(np.asarray, out["train"]["params"])


def test_cli_trains_with_it_and_refuses_a_share_above_one(tmp_path, capsys):
    from dataset_factory import train_tiny_cli

    from thrombojax.cli import main
    from thrombojax.train.state import load_trained

    data, run = train_tiny_cli(tmp_path, "--average-weights", "0.5", n_nodes=60)
    assert load_trained(run, which="last").run.train.average_weights == 0.5
    capsys.readouterr()
    assert main(["train", "--dataset", str(data), "--model", "mgn", "--tiny", "--epochs", "1",
                 "--out", str(tmp_path / "bad"), "--average-weights", "1.5", "--quiet"]) == 2
    assert "--average-weights (average_weights) must be <= 1" in capsys.readouterr().err
