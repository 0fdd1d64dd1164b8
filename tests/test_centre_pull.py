"""The centring pull of the vessel-following prior (:func:`thrombojax.graph.section
.section_offset`, :func:`~thrombojax.graph.section.centre_pull`, ``make_step(...,
centre_pull=K)``, ``thrombojax train --centre-pull K``): the prior turns the clot onto the
vessel's axis but, without the pull, nothing brings a clot that drifted back to the middle."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_section import _clot_in_tube

from thrombojax.errors import ConfigError
from thrombojax.graph.section import centre_pull, section_offset
from thrombojax.graph.vessel_axis import follow_axis_offset, vessel_axis
from thrombojax.models import create_model, get_config
from thrombojax.simulator.step import make_step
from thrombojax.types import NodeType

ROT = Rotation.from_euler("xyz", [0.4, 2.1, -1.3]).as_matrix().astype(np.float32)


def _offset(x, nt, mask, with_axis=True):
    x = jnp.asarray(x)
    axis = vessel_axis(x, nt, mask, radius=2.0) if with_axis else None
    e, ok = section_offset(x, nt, mask, unit=1.0, axis=axis)
    return np.asarray(e), bool(ok)


def test_the_offset_is_where_the_clot_sits_across_the_tube_and_turns_with_it():
    """A tube of radius 1 along x: the offset is the clot centroid's (y, z), 0.4 r more along
    y when the clot is moved 0.4 r along y, with the axis from the wall normals or from the
    nodes' spread; nothing along the axis; the offset turns with the frame."""
    centred, nt, mask = _clot_in_tube(np.random.default_rng(0))
    off, _, _ = _clot_in_tube(np.random.default_rng(0), centre=(0.3, 0.4, 0.0))
    clot = (nt == NodeType.CLOT) & mask
    across = centred[1][clot].mean(axis=0) * np.array([0.0, 1.0, 1.0])  # the random ball's
    e0, ok0 = _offset(centred[1], nt, mask)
    assert ok0 and e0 == pytest.approx(across, abs=0.01)
    for with_axis in (True, False):
        e, ok = _offset(off[1], nt, mask, with_axis)
        # within 0.03 r: the cross-section's ball weighs the nearer wall a little more
        assert ok and e == pytest.approx(across + [0.0, 0.4, 0.0], abs=0.03)
    e_rot, ok = _offset(off[1] @ ROT.T + np.float32(2.0), nt, mask)
    # within 0.01 r: the wall normals' nearest nodes tie on a tube's rings and the turned
    # coordinates' rounding breaks the ties otherwise (tests/test_step_inputs.py)
    assert ok and e_rot == pytest.approx(e @ ROT.T, abs=0.01)


def test_there_is_no_middle_past_an_open_end_and_no_pull_there():
    """Past the tube's end (the clot's centroid 1.5 r beyond it) the cross-section is not a
    ring: no middle, no offset, no pull."""
    x, nt, mask = _clot_in_tube(np.random.default_rng(1), centre=(5.5, 0.4, 0.0))
    e, ok = _offset(x[1], nt, mask)
    assert not ok and np.all(e == 0.0)
    pull = centre_pull(jnp.asarray(x[1]), nt, mask, unit=1.0, strength=0.5,
                       axis=vessel_axis(jnp.asarray(x[1]), nt, mask, radius=2.0))
    assert np.all(np.asarray(pull) == 0.0)


def test_the_pull_takes_back_its_share_of_the_offset_beyond_the_tolerance():
    x, nt, mask = _clot_in_tube(np.random.default_rng(0), centre=(0.0, 0.4, 0.0))
    e, _ = _offset(x[1], nt, mask)
    axis = vessel_axis(jnp.asarray(x[1]), nt, mask, radius=2.0)

    def pull(strength, tolerance):
        return np.asarray(centre_pull(jnp.asarray(x[1]), nt, mask, unit=1.0, strength=strength,
                                      tolerance=tolerance, axis=axis))

    assert pull(0.5, 0.0) == pytest.approx(-0.5 * e, abs=1e-6)
    excess = np.linalg.norm(e) - 0.3
    assert pull(0.5, 0.3) == pytest.approx(-0.5 * excess * e / np.linalg.norm(e), abs=1e-6)
    assert np.all(pull(0.5, 0.5) == 0.0)  # within the tolerance


def _roll_prior(x, nt, mask, steps, strength):
    """The prior alone (no model), ``steps`` frames on from ``x [2, N, 3]``; returns the
    centroid offsets from the middle and the clot nodes' speeds of every step."""
    clot = (nt == NodeType.CLOT) & mask
    prev, cur = jnp.asarray(x[0]), jnp.asarray(x[1])
    offsets, speeds = [], []
    for _ in range(steps):
        t = vessel_axis(cur, nt, mask, radius=2.0)
        pull = None if strength == 0 else centre_pull(cur, nt, mask, unit=1.0,
                                                      strength=strength, axis=t)
        nxt = cur + (cur - prev) + follow_axis_offset(prev, cur, nt, mask, radius=2.0, axis=t,
                                                      pull=pull)
        prev, cur = cur, nxt
        offsets.append(np.linalg.norm(_offset(cur, nt, mask)[0]))
        speeds.append(np.linalg.norm(np.asarray(cur - prev)[clot], axis=1))
    return np.asarray(offsets), np.asarray(speeds)


def test_the_prior_alone_keeps_a_drifted_clot_off_the_middle_and_the_pull_brings_it_back():
    """A clot 0.4 r off the middle moving along a straight tube: the prior alone keeps it 0.4 r
    off for 10 steps; with the pull (half the offset per step) it is back within 0.05 r, each
    node at the speed it had (the pull turns the velocities, it does not speed them up)."""
    x, nt, mask = _clot_in_tube(np.random.default_rng(2), centre=(-2.0, 0.4, 0.0), speed=0.1)
    alone, speed_alone = _roll_prior(x, nt, mask, 10, 0.0)
    pulled, speed_pulled = _roll_prior(x, nt, mask, 10, 0.5)
    assert alone.min() > 0.35
    assert pulled[-1] < 0.05 and np.all(np.diff(pulled[:5]) < 0)
    assert speed_pulled == pytest.approx(speed_alone, rel=1e-4)
    assert speed_alone == pytest.approx(0.1, rel=1e-4)


def _step(**options):
    model = create_model("mgn", get_config("mgn", tiny=True, max_neighbors=8))
    return make_step(model, **options)


def test_the_step_adds_the_pull_to_its_prior_and_refuses_it_without_one():
    x, nt, mask = _clot_in_tube(np.random.default_rng(0), centre=(0.0, 0.4, 0.0), speed=0.1)
    plain = _step(prior_radius=2.0)
    pulled = _step(prior_radius=2.0, centre_pull=0.5, centre_unit=1.0)
    args = (jnp.asarray(x[0]), jnp.asarray(x[1]), nt, mask)
    clot = (nt == NodeType.CLOT) & mask
    moved = np.asarray(pulled.prior(*args) - plain.prior(*args))[clot]
    assert moved[:, 1].mean() < -0.01  # toward the middle (y = 0)
    assert np.all(np.asarray(jax.jit(pulled.prior)(*args))[~clot] == 0.0)
    for bad in ({"centre_pull": 0.5, "centre_unit": 1.0},  # no prior
                {"prior_radius": 2.0, "centre_pull": 1.5, "centre_unit": 1.0},
                {"prior_radius": 2.0, "centre_pull": 0.5}):  # no vessel radius
        with pytest.raises(ConfigError, match="centre_pull"):
            _step(**bad)


def test_cli_refuses_a_pull_without_the_prior_or_above_one(tmp_path, capsys):
    from dataset_factory import tiny_cli_dataset

    from thrombojax.cli import main

    data = tiny_cli_dataset(tmp_path)
    for flags, words in ((["--recipe", "study", "--centre-pull", "0.5"], "--follow-axis"),
                         (["--centre-pull", "1.5"], "<= 1")):
        code = main(["train", "--dataset", str(data), "--out", str(tmp_path / "r"), "--tiny",
                     *flags, "--quiet"])
        assert code != 0 and words in capsys.readouterr().err
        assert not (tmp_path / "r").exists()


class _Tubes:
    """A dataset-like pair of straight-tube simulations whose clots sit 0.1 r and 0.3 r off
    the middle in every frame."""
    path = "tubes.h5"

    def __init__(self):
        self.sims = {f"s{i}": _clot_in_tube(np.random.default_rng(i), centre=(0.0, off, 0.0))
                     for i, off in enumerate((0.1, 0.3))}

    def positions(self, name):
        return self.sims[name][0]

    def node_type(self, name):
        return self.sims[name][1]


def test_auto_tolerance_is_the_quantile_of_the_true_offsets():
    """``--centre-tolerance auto``: the offsets of the training frames as the prior reads them
    (each clot's random centroid plus its shift), pooled, at the quantile asked."""
    from thrombojax.train.centre_fit import fit_pull_tolerance, pull_offsets

    ds = _Tubes()
    offsets = {}
    for name, (x, nt, mask) in ds.sims.items():
        nt = np.where(mask, nt, NodeType.VESSEL)  # the dataset has no padding: far wall nodes
        ds.sims[name] = (x, nt, mask)
        off, ok = pull_offsets(x, nt, radius=1.0, axis_width=2.0)
        assert ok.all()
        offsets[name] = off
    assert offsets["s0"] == pytest.approx(0.1, abs=0.04)
    assert offsets["s1"] == pytest.approx(0.3, abs=0.04)
    fit = fit_pull_tolerance(ds, ["s0", "s1"], radius=1.0, axis_width=2.0, skip=0, nodes=None,
                             seed=0, quantile=1.0)
    assert fit["centre_tolerance_r"] == pytest.approx(offsets["s1"].max(), rel=1e-5)
    assert (fit["frames"], fit["simulations"]) == (6, ["s0", "s1"])
    low = fit_pull_tolerance(ds, ["s0"], radius=1.0, axis_width=2.0, skip=1, nodes=None, seed=0)
    assert low["frames"] == 2 and low["centre_tolerance_r"] < 0.15


class _Trained:
    """What :func:`thrombojax.eval.rollout_pull.rollout_pull` reads of a trained run."""

    class run:  # noqa: N801
        class train:  # noqa: N801
            follow_axis, skip_frames, nodes_per_sample, seed = 2.0, 0, None, 0

    class split:  # noqa: N801
        train = ("s0", "s1")


def test_rollout_time_pull_sets_the_strength_unit_and_fitted_tolerance_or_refuses():
    """``thrombojax rollout --centre-pull K``: the run's step with the pull at strength K, the
    rolled-out vessel's radius as its unit, the tolerance given or fitted (``auto``) on the
    run's training simulations as training fits it; the step then pulls a drifted clot."""
    from thrombojax.eval.rollout_pull import rollout_pull

    plain = _step(prior_radius=4.0)
    reads = []

    def training_ds():
        reads.append(1)
        tubes = _Tubes()
        for name, (x, nt, mask) in tubes.sims.items():  # no padding in a dataset
            tubes.sims[name] = (x, np.where(mask, nt, NodeType.VESSEL), mask)
        tubes.attrs = {"vessel_radius": 1.0, "skip_frames": 0}
        return tubes

    kept, record = rollout_pull(plain, _Trained, training_ds, strength=None, tolerance=None,
                                radius=2.0, run_dir="run")
    assert kept is plain and record["at"] is None and not reads
    pulled, record = rollout_pull(plain, _Trained, training_ds, strength=0.5, tolerance=0.25,
                                  radius=2.0, run_dir="run")
    assert (pulled.centre_pull, pulled.centre_unit, pulled.centre_tolerance) == (0.5, 2.0, 0.5)
    assert record == {"at": "rollout", "strength": 0.5, "tolerance_r": 0.25, "fit": None}
    assert not reads and pulled.prior_radius == plain.prior_radius
    x, nt, mask = _clot_in_tube(np.random.default_rng(0), centre=(0.0, 0.8, 0.0), speed=0.1,
                                radius=2.0)
    args = (jnp.asarray(x[0]), jnp.asarray(x[1]), nt, mask)
    moved = np.asarray(pulled.prior(*args) - plain.prior(*args))[(nt == NodeType.CLOT) & mask]
    assert moved[:, 1].mean() < -0.01  # toward the middle (y = 0)
    auto, record = rollout_pull(plain, _Trained, training_ds, strength=1.0, tolerance="auto",
                                radius=2.0, run_dir="run")
    assert reads == [1] and record["fit"]["simulations"] == ["s0", "s1"]
    assert record["tolerance_r"] == pytest.approx(record["fit"]["centre_tolerance_r"])
    assert auto.centre_tolerance == pytest.approx(2.0 * record["tolerance_r"])
    assert 0.1 < record["tolerance_r"] < 0.3  # the median of clots 0.1 r and 0.3 r off
    for strength, tolerance, step, words in ((None, 0.1, plain, "--centre-pull K"),
                                             (1.5, None, plain, "(0, 1]"),
                                             (0.5, 0.0, _step(), "--follow-axis")):
        with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace("]", r"\]")):
            rollout_pull(step, _Trained, training_ds, strength=strength, tolerance=tolerance,
                         radius=2.0, run_dir="run")
