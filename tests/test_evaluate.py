"""evaluate / rollout commands end to end on a tiny synthetic dataset and a 1-epoch run."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from dataset_factory import accelerating_sims
from PIL import Image

from thrombojax.cli import main
from thrombojax.types import NodeType

pytestmark = pytest.mark.slow  # a minute or more: scheduled first (tests/conftest.py)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from thrombojax.io.hdf5 import write_dataset
    from thrombojax.train.loop import train

    root = tmp_path_factory.mktemp("eval")
    sims = accelerating_sims(attrs={"solver_wall_time_s": 2.0})
    data = write_dataset(root / "tiny.h5", sims, name="tiny-bend", source="test")
    run = root / "run"
    train(data, "mgn", run, epochs=1, tiny=True, n_val=1, batch_size=2, progress=False)
    return data, run, root


def _times(path, tag, key):
    import xml.etree.ElementTree as ET

    return [float(e.get(key)) for e in ET.parse(path).getroot().iter(tag)]


def test_evaluate_command_writes_json_and_table(tiny_run, capsys):
    data, run, root = tiny_run
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(root / "ev"), "--quiet"]) == 0
    res = json.loads((root / "ev" / "evaluate.json").read_text())
    test_sim = json.loads((run / "config.json").read_text())["split"]["test"][0]
    assert list(res["simulations"]) == [test_sim]
    assert res["simulations"][test_sim]["windows"] == 10
    assert res["mse"] > 0 and res["constant_velocity_mse"] > 0
    assert "constant velocity MSE" in (root / "ev" / "evaluate.md").read_text()
    assert "constant velocity" in capsys.readouterr().out
    # where the figures were measured: device, versions, command, load, in JSON and markdown
    import jax

    env = res["environment"]
    assert env["jax"] == jax.__version__ and env["device"].startswith("cpu")
    assert env["command"] and len(env["load_avg_1_5_15"]) == 3  # the process's own command
    assert f"- jax: {jax.__version__}" in (root / "ev" / "evaluate.md").read_text()


def test_rollout_command_writes_everything(tiny_run):
    from thrombojax.io.hdf5 import open_dataset

    data, run, root = tiny_run
    out = root / "ro"
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--sim", "sim_0", "--skip", "5", "--nodes", "100"]) == 0
    rep = json.loads((out / "rollout.json").read_text())["simulations"]["sim_0"]
    assert rep["t0"] == 5 and rep["n_steps"] == 6 and rep["n_nodes"] == 100
    assert set(rep["curves"]) == {"mgn", "constant velocity", "ground truth"}
    # constant velocity has the known error of a constant acceleration: grows like k^2
    mse_cv = np.asarray(rep["curves"]["constant velocity"]["mse"])
    assert (np.diff(mse_cv) > 0).all()
    assert rep["summary"]["ground truth"]["max_fraction_outside"] == 0.0
    ro = open_dataset(out / "sim_0_rollout.h5")
    sim = ro[ro.names[0]]
    assert sim.positions.shape == (8, 100, 3)
    full = open_dataset(data)["sim_0"]
    idx = np.asarray(rep["node_index"])
    np.testing.assert_allclose(sim.positions[:2], full.positions[4:6, idx], atol=1e-5)
    vessel = sim.node_type == NodeType.VESSEL
    assert np.array_equal(sim.positions[:, vessel], np.repeat(sim.positions[:1, vessel], 8, 0))
    for f in ("sim_0_prediction.xdmf", "sim_0_truth.xdmf", "sim_0_error.png",
              "sim_0_metrics.png", "rollout.md"):
        assert (out / f).is_file(), f
    assert Image.open(out / "sim_0_rollout.gif").n_frames == 8
    assert main(["export", str(out / "sim_0_rollout.h5"), "--out", str(root / "ex"),
                 "--format", "vtu"]) == 0
    assert (root / "ex" / "sim_0_rollout.pvd").is_file()
    # physical times frame * dt everywhere: the rollout starts at frame t0 - 1 = 4
    assert _times(root / "ex" / "sim_0_rollout.pvd", "DataSet", "timestep") == \
        pytest.approx((4 + np.arange(8)) * 0.01)
    assert _times(out / "sim_0_prediction.xdmf", "Time", "Value") == \
        pytest.approx((4 + np.arange(8)) * 0.01)
    assert main(["export", str(data), "--out", str(root / "ex"), "--sim", "sim_0"]) == 0
    assert _times(root / "ex" / "sim_0.xdmf", "Time", "Value") == \
        pytest.approx(np.arange(12) * 0.01)
    assert Image.open(out / "sim_0_summary.png").size[0] > 600
    assert "Dataset length unit: vessel radius" in (out / "rollout.md").read_text()
    # where the figures were measured, and from which checkpoint
    import jax

    top = json.loads((out / "rollout.json").read_text())
    assert top["checkpoint"] == "best" and top["environment"]["jax"] == jax.__version__
    assert f"- jax: {jax.__version__}" in (out / "rollout.md").read_text()
    assert main(["rollout", "--run", str(run), "--dataset", str(data), "--out", str(out),
                 "--sim", "nope"]) == 2
    # a dataset in another length unit is refused, not scaled silently
    assert json.loads((run / "config.json").read_text())["units"] == "vessel radius"
    from thrombojax.io.hdf5 import write_dataset

    src = open_dataset(data)
    mm = write_dataset(root / "mm.h5", [src[n] for n in src.names], name="mm", source="t",
                       units="mm")
    assert main(["rollout", "--run", str(run), "--dataset", str(mm), "--out", str(out)]) == 2


def _other_dataset(data, path, *, rename: bool, units: str = "", skip_frames: int = 4):
    """Dataset B from the run's dataset A: the clots move 10 % faster, another unit record
    (``""``: the vessel radius is estimated), its own ``skip_frames``; renamed or not."""
    from thrombojax.io.hdf5 import Simulation, open_dataset, write_dataset

    src = open_dataset(data)
    sims = []
    for name in src.names:
        s = src[name]
        pos = s.positions.copy()
        clot = s.node_type == NodeType.CLOT
        pos[:, clot] += 0.1 * (pos[:, clot] - pos[:1, clot])
        sims.append(Simulation(name=f"other_{name}" if rename else name, positions=pos,
                               node_type=s.node_type, attrs=s.attrs))
    return write_dataset(path, sims, name="other", source="test", units=units,
                         skip_frames=skip_frames)


def test_evaluate_by_phase_in_radii_on_another_dataset(tiny_run, capsys):
    """Train on A, evaluate on B in one command: all of B, phases at B's skip_frames, errors in
    vessel radii from B's geometry, model beside constant velocity."""
    data, run, root = tiny_run
    other = _other_dataset(data, root / "b_renamed.h5", rename=True)
    assert main(["evaluate", "--run", str(run), "--dataset", str(other), "--out",
                 str(root / "ev_b"), "--quiet"]) == 0
    res = json.loads((root / "ev_b" / "evaluate.json").read_text())
    assert sorted(res["simulations"]) == [f"other_sim_{i}" for i in range(4)]
    assert res["selection"]["how"].startswith("all 4 simulations of the dataset")
    assert "all 4 simulations" in capsys.readouterr().out
    # B's own skip_frames (4) splits the windows t = 1..10: start t < 4, rollout t >= 4
    assert res["skip_frames"] == 4
    ph = res["phases"]
    assert (ph["all"]["windows"], ph["start"]["windows"], ph["rollout"]["windows"]) == \
        (40, 12, 28)
    assert ph["exit"]["windows"] == 0  # the clots never leave the tube
    assert ph["rollout_before_exit"]["windows"] == 28
    # vessel radius estimated from B's wall (a tube of radius 0.18 x 10 = 1.8)
    u = res["units"]
    assert "estimated" in u["vessel_radius_source"]
    assert u["vessel_radius"] == pytest.approx(1.8, rel=0.1)
    scale = json.loads((run / "config.json").read_text())["scaling"]["scale"]
    assert u["scale"] == pytest.approx(scale)
    factor = scale / u["vessel_radius"]
    for p in ph.values():
        if p["windows"]:
            assert p["mse_r2"] == pytest.approx(p["mse"] * factor**2)
            assert p["rmse_r"] == pytest.approx(np.sqrt(p["mse"]) * factor)
            assert p["ratio_to_cv"] == pytest.approx(p["mse"] / p["constant_velocity_mse"])
    # the phases are window-weighted parts of the whole
    assert ph["all"]["mse"] == pytest.approx(
        (12 * ph["start"]["mse"] + 28 * ph["rollout"]["mse"]) / 40)
    md = (root / "ev_b" / "evaluate.md").read_text()
    for text in ("constant velocity MSE (r^2)", "| rollout |", "| start |", "estimated from",
                 "skip_frames = 4"):
        assert text in md, text


def test_evaluate_selects_simulations(tiny_run):
    data, run, root = tiny_run
    # --sim on evaluate: exactly those
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(root / "ev_sim"), "--sim", "sim_2", "--sim", "sim_0", "--quiet"]) == 0
    res = json.loads((root / "ev_sim" / "evaluate.json").read_text())
    assert list(res["simulations"]) == ["sim_2", "sim_0"]
    assert res["units"]["vessel_radius"] == 1.0  # A is in vessel radii
    assert main(["evaluate", "--run", str(run), "--dataset", str(data), "--out",
                 str(root / "ev_sim"), "--sim", "nope", "--force", "--quiet"]) == 2
    # B has A's names but other content: not the run's dataset, so all of it
    same_names = _other_dataset(data, root / "b_same_names.h5", rename=False,
                                units="vessel radius")
    assert main(["evaluate", "--run", str(run), "--dataset", str(same_names), "--out",
                 str(root / "ev_same"), "--quiet"]) == 0
    res = json.loads((root / "ev_same" / "evaluate.json").read_text())
    assert len(res["simulations"]) == 4 and "not the run's training dataset" in \
        res["selection"]["how"]
    # --split still picks the run's split on any dataset
    assert main(["evaluate", "--run", str(run), "--dataset", str(same_names), "--out",
                 str(root / "ev_same"), "--split", "test", "--force", "--quiet"]) == 0
    test_sims = json.loads((run / "config.json").read_text())["split"]["test"]
    assert list(json.loads((root / "ev_same" / "evaluate.json").read_text())["simulations"]) \
        == test_sims


def test_rollout_reports_radii_phases_and_ratios_on_another_dataset(tiny_run):
    data, run, root = tiny_run
    other = root / "b_renamed.h5"
    if not other.exists():
        _other_dataset(data, other, rename=True)
    out = root / "ro_b"
    assert main(["rollout", "--run", str(run), "--dataset", str(other), "--out", str(out),
                 "--no-gif", "--nodes", "100", "--quiet"]) == 0
    res = json.loads((out / "rollout.json").read_text())
    assert sorted(res["simulations"]) == [f"other_sim_{i}" for i in range(4)]
    assert res["skip_frames"] == 4 and res["units"]["vessel_radius"] == pytest.approx(1.8,
                                                                                       rel=0.1)
    factor = res["units"]["radii_per_scaled_unit"]
    for rep in res["simulations"].values():
        assert rep["t0"] == 4  # the dataset's attribute, whatever the file is called
        model, cv = rep["summary"]["mgn"], rep["summary"]["constant velocity"]
        for s in (model, cv):
            assert s["mse@full_r2"] == pytest.approx(s["mse@full"] * factor**2)
            assert s["final_centroid_error_r"] == pytest.approx(
                s["final_centroid_error"] * factor)
        assert model["ratio_to_cv"]["mse@full"] == pytest.approx(model["mse@full"] /
                                                                  cv["mse@full"])
        np.testing.assert_allclose(rep["curves"]["mgn"]["rmse_r"],
                                   np.sqrt(rep["curves"]["mgn"]["mse"]) * factor)
        ss = rep["single_step"]
        assert ss["start"]["windows"] == 3 and ss["rollout"]["windows"] == 7
        assert ss["rollout"]["constant_velocity_mse"] > 0
    md = (out / "rollout.md").read_text()
    for text in ("## In vessel radii", "1-step MSE rollout phase (r^2)", "MSE@10 (r^2)",
                 "final centroid error (r)", "max % outside", "MSE@full / CV",
                 "| **mean** | constant velocity |", "## In scaled [-1, 1] coordinates"):
        assert text in md, text


def test_rollout_guards_on_by_default_and_off_for_the_model_alone(tiny_run):
    """Guards report their per-step corrections; --no-guards rolls the model out alone."""
    data, run, root = tiny_run
    common = ["rollout", "--run", str(run), "--dataset", str(data), "--sim", "sim_1",
              "--no-gif", "--quiet"]
    assert main([*common, "--out", str(root / "guarded")]) == 0
    assert main([*common, "--out", str(root / "alone"), "--no-guards"]) == 0
    on = json.loads((root / "guarded" / "rollout.json").read_text())
    off = json.loads((root / "alone" / "rollout.json").read_text())
    assert on["guards"] and not off["guards"]
    curves_on = on["simulations"]["sim_1"]["curves"]["mgn"]
    curves_off = off["simulations"]["sim_1"]["curves"]["mgn"]
    assert {"guard_containment", "guard_coherence"} <= set(curves_on)
    assert not any(k.startswith("guard_") for k in curves_off)
    assert all(v >= 0 for v in curves_on["guard_containment"])
    assert "Guards: off (the model alone)." in (root / "alone" / "rollout.md").read_text()
    assert "Guards: on: containment; coherence" in (root / "guarded" / "rollout.md").read_text()


def test_rollout_centring_adds_the_centring_guard(tiny_run, capsys):
    """--centring R turns the centring guard on beside the default guards, records R and the
    guard's per-step correction; without the guards it is refused, naming both options."""
    data, run, root = tiny_run
    common = ["rollout", "--run", str(run), "--dataset", str(data), "--sim", "sim_1",
              "--no-gif", "--quiet"]
    assert main([*common, "--out", str(root / "centred"), "--centring", "0.15"]) == 0
    rep = json.loads((root / "centred" / "rollout.json").read_text())
    assert rep["guards"] and rep["centring_r"] == 0.15
    curves = rep["simulations"]["sim_1"]["curves"]["mgn"]
    assert {"guard_centring", "guard_containment", "guard_coherence"} <= set(curves)
    assert all(v >= 0 for v in curves["guard_centring"])
    assert "max_guard_centring" in rep["simulations"]["sim_1"]["summary"]["mgn"]
    capsys.readouterr()
    assert main([*common, "--out", str(root / "centred_alone"), "--no-guards",
                 "--centring", "0.15"]) == 2
    assert "--centring with --no-guards" in capsys.readouterr().err
    assert not (root / "centred_alone").exists()


def test_rollout_coherence_tolerance_reaches_the_guard(tiny_run, capsys):
    """--coherence-tolerance R sets the coherence guard's tolerance and records it: at 0 every
    deviation from the rigid start is pulled back, so the guard moves nodes further than at
    1 r; the default is 'auto', the tolerance fitted on the run's training simulations
    (recorded with the fit); without the guards it is refused, naming both options."""
    from thrombojax import study
    from thrombojax.data.radius import vessel_radius
    from thrombojax.eval.coherence_fit import fit_coherence
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.train.state import load_trained

    data, run, root = tiny_run
    common = ["rollout", "--run", str(run), "--dataset", str(data), "--sim", "sim_1",
              "--no-gif", "--quiet"]
    largest = {}
    reps, largest = {}, {}
    for label, extra in (("fixed", ["--coherence-tolerance", "1"]),
                         ("rigid", ["--coherence-tolerance", "0"]), ("default", [])):
        assert main([*common, "--out", str(root / f"coherence_{label}"), *extra]) == 0
        reps[label] = rep = json.loads((root / f"coherence_{label}" / "rollout.json").read_text())
        assert rep["guards"]
        largest[label] = max(rep["simulations"]["sim_1"]["curves"]["mgn"]["guard_coherence"])
    assert reps["fixed"]["coherence_r"] == 1.0 and reps["rigid"]["coherence_r"] == 0.0
    assert reps["fixed"]["coherence_fit"] is None is reps["rigid"]["coherence_fit"]
    assert largest["rigid"] > max(largest["fixed"], 0.0)
    ds = open_dataset(data)
    trained = load_trained(run)
    want = fit_coherence(ds, trained.split.train, float(vessel_radius(ds)), study.skip_frames(ds))
    assert reps["default"]["coherence_fit"] == want
    assert reps["default"]["coherence_r"] == want["coherence_r"] > 0
    said = (root / "coherence_default" / "rollout.md").read_text()
    assert f"coherence with a tolerance of {want['coherence_r']:.3g} r (fitted on the run's" in said
    assert "tolerance of 0 r (fixed)" in (root / "coherence_rigid" / "rollout.md").read_text()
    assert want["simulations"] == list(trained.split.train)
    capsys.readouterr()
    assert main([*common, "--out", str(root / "coherence_alone"), "--no-guards",
                 "--coherence-tolerance", "0.5"]) == 2
    assert "--coherence-tolerance with --no-guards" in capsys.readouterr().err
    assert not (root / "coherence_alone").exists()
    # --coherence-stretch: the copy may stretch; 'auto' is fitted to that copy and recorded
    assert main([*common, "--out", str(root / "coherence_stretch"),
                 "--coherence-stretch", "1.2"]) == 0
    rep = json.loads((root / "coherence_stretch" / "rollout.json").read_text())
    bent = fit_coherence(ds, trained.split.train, float(vessel_radius(ds)),
                         study.skip_frames(ds), max_stretch=1.2)
    assert rep["coherence_stretch"] == 1.2 and rep["coherence_fit"] == bent
    assert rep["coherence_r"] == bent["coherence_r"]
    assert "stretching up to 1.2x at constant volume" in (
        root / "coherence_stretch" / "rollout.md").read_text()
    capsys.readouterr()
    assert main([*common, "--out", str(root / "stretch_alone"), "--no-guards",
                 "--coherence-stretch", "1.2"]) == 2
    assert "--coherence-stretch with --no-guards" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: S must be >= 1
        main([*common, "--out", str(root / "stretch_low"), "--coherence-stretch", "0.9"])
    assert not (root / "stretch_alone").exists() and not (root / "stretch_low").exists()


def test_rollout_keep_wall_velocity_reaches_the_guard(tiny_run, capsys, monkeypatch):
    """--keep-wall-velocity builds the guards with ``keep_velocity_wall`` (off by default),
    records it and names it in rollout.md; without the guards it is refused."""
    import thrombojax.eval.rollouts as rollouts

    data, run, root = tiny_run
    common = ["rollout", "--run", str(run), "--dataset", str(data), "--sim", "sim_1",
              "--no-gif", "--quiet", "--coherence-tolerance", "1"]
    built, real = [], rollouts.build_guards
    monkeypatch.setattr(rollouts, "build_guards",
                        lambda *a, **k: built.append(k["keep_velocity_wall"]) or real(*a, **k))
    for label, extra in (("plain", []), ("kept", ["--keep-wall-velocity"])):
        assert main([*common, "--out", str(root / f"wallvel_{label}"), *extra]) == 0
    assert built == [False, True]
    plain, kept = (json.loads((root / f"wallvel_{x}" / "rollout.json").read_text())
                   for x in ("plain", "kept"))
    assert plain["keep_wall_velocity"] is False and kept["keep_wall_velocity"] is True
    said = "the step after containment reads the velocity from before it"
    assert said in (root / "wallvel_kept" / "rollout.md").read_text()
    assert said not in (root / "wallvel_plain" / "rollout.md").read_text()
    capsys.readouterr()
    assert main([*common[:-2], "--out", str(root / "wallvel_alone"), "--no-guards",
                 "--keep-wall-velocity"]) == 2
    assert "--keep-wall-velocity with --no-guards" in capsys.readouterr().err
    assert not (root / "wallvel_alone").exists()


def test_rollout_of_an_ensemble_reports_its_spread(tiny_run):
    """An ensemble folder rolls out as one program: mean prediction, spread beside the error."""
    from thrombojax.train.ensemble import train_ensemble

    data, _, root = tiny_run
    train_ensemble(data, "mgn", root / "ens", 2, epochs=1, tiny=True, n_val=1, batch_size=2,
                   warmup_epochs=0.0, progress=False)
    assert main(["rollout", "--run", str(root / "ens"), "--dataset", str(data), "--sim",
                 "sim_0", "--out", str(root / "ens_ro"), "--no-gif", "--quiet"]) == 0
    rep = json.loads((root / "ens_ro" / "rollout.json").read_text())
    assert rep["ensemble_members"] == 2
    spread = rep["simulations"]["sim_0"]["curves"]["mgn"]["spread"]
    assert len(spread) == rep["simulations"]["sim_0"]["n_steps"] and max(spread) > 0
    unc = rep["simulations"]["sim_0"]["summary"]["mgn"]["uncertainty"]
    assert {"spearman", "calibration", "within_2_spread"} <= set(unc)


def test_rollout_rotations_make_a_rotation_ensemble(tiny_run):
    """--rotations R: one model on R turned copies (its spread reported as an ensemble's);
    --rotations 1 is the identity alone, the plain rollout; an ensemble's M members x R."""
    data, run, root = tiny_run
    common = ["--dataset", str(data), "--sim", "sim_0", "--no-gif", "--quiet", "--no-guards"]
    outs = {}
    for name, extra in (("plain", []), ("rot1", ["--rotations", "1"]),
                        ("rot3", ["--rotations", "3"])):
        assert main(["rollout", "--run", str(run), "--out", str(root / name), *common,
                     *extra]) == 0
        outs[name] = json.loads((root / name / "rollout.json").read_text())
    assert outs["rot3"]["ensemble_members"] == 3 and outs["rot3"]["rotations"] == 3
    assert outs["plain"]["ensemble_members"] == 1 and outs["plain"]["rotations"] == 0
    err = {k: v["simulations"]["sim_0"]["curves"]["mgn"]["mse"] for k, v in outs.items()}
    np.testing.assert_allclose(err["rot1"], err["plain"], rtol=1e-5, atol=0)
    assert not np.allclose(err["rot3"], err["plain"])  # a tiny model is far from equivariant
    assert max(outs["rot3"]["simulations"]["sim_0"]["curves"]["mgn"]["spread"]) > 0
    # the single-step table is the unturned model's in every case
    assert outs["rot3"]["simulations"]["sim_0"]["single_step"] == \
        outs["plain"]["simulations"]["sim_0"]["single_step"]
    if (root / "ens").is_dir():  # the ensemble of the test above: 2 members x 2 copies
        assert main(["rollout", "--run", str(root / "ens"), "--out", str(root / "ens_rot"),
                     *common, "--rotations", "2"]) == 0
        assert json.loads((root / "ens_rot" / "rollout.json").read_text())[
            "ensemble_members"] == 4


def test_train_members_cli_makes_an_ensemble(tiny_run, capsys):
    data, _, root = tiny_run
    assert main(["train", "--dataset", str(data), "--model", "mgn", "--out",
                 str(root / "cli_ens"), "--members", "2", "--epochs", "1", "--tiny",
                 "--n-val", "1", "--batch-size", "2", "--warmup-epochs", "0", "--quiet"]) == 0
    assert "ensemble of 2 mgn members" in capsys.readouterr().out
    assert (root / "cli_ens" / "ensemble.json").is_file()


def test_rollout_centring_auto_fits_the_tolerance_on_the_training_simulations(tiny_run,
                                                                              capsys):
    """--centring auto: the tolerance is fitted on the run's training simulations of its own
    dataset (recorded with the fit), the same as fit_centring gives; a run whose dataset has
    gone is refused with a message that names it and asks for a number."""
    from thrombojax.data.radius import vessel_radius
    from thrombojax.eval.centring_fit import fit_centring
    from thrombojax.io.hdf5 import open_dataset
    from thrombojax.train.state import load_trained

    data, run, root = tiny_run
    common = ["rollout", "--dataset", str(data), "--sim", "sim_1", "--no-gif", "--quiet"]
    assert main([*common, "--run", str(run), "--out", str(root / "auto"), "--centring",
                 "auto"]) == 0
    rep = json.loads((root / "auto" / "rollout.json").read_text())
    trained = load_trained(run)
    ds = open_dataset(data)
    want = fit_centring(ds, trained.split.train, float(vessel_radius(ds)))
    assert rep["centring_fit"] == want and rep["centring_r"] == want["centring_r"] > 0
    assert rep["centring_fit"]["simulations"] == list(trained.split.train)
    assert "max_guard_centring" in rep["simulations"]["sim_1"]["summary"]["mgn"]
    moved = root / "run_elsewhere"
    shutil.copytree(run, moved)
    config = json.loads((moved / "config.json").read_text())
    config["dataset"] = str(root / "gone.h5")
    (moved / "config.json").write_text(json.dumps(config))
    capsys.readouterr()
    assert main([*common, "--run", str(moved), "--out", str(root / "auto_gone"),
                 "--centring", "auto"]) == 2
    err = capsys.readouterr().err
    assert "gone.h5" in err and "give --centring a number" in err
    assert not (root / "auto_gone").exists()
    assert main([*common, "--run", str(moved), "--out", str(root / "auto_gone"),
                 "--coherence-tolerance", "auto"]) == 2
    err = capsys.readouterr().err
    assert "gone.h5" in err and "give --coherence-tolerance a number" in err
    assert not (root / "auto_gone").exists()
    # by default the coherence tolerance is 'auto' where it can be, else the fixed 1 r, said
    assert main([*common, "--run", str(moved), "--out", str(root / "fixed_gone")]) == 0
    err = capsys.readouterr().err
    assert "warning: the coherence tolerance was not fitted" in err and "gone.h5" in err
    assert "keeps the fixed tolerance of 1 r" in err
    rep = json.loads((root / "fixed_gone" / "rollout.json").read_text())
    assert rep["coherence_r"] == 1.0 and rep["coherence_fit"] is None
