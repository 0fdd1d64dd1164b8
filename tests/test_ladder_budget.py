"""The ladder's time budget: the calibration epoch is timed at the rung's full k."""

import importlib.util
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _ladder(monkeypatch):
    spec = importlib.util.spec_from_file_location("ladder", ROOT / "experiments" / "ladder.py")
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "ladder", module)  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_calibration_times_the_full_k_step_loss(tmp_path, monkeypatch):
    ladder = _ladder(monkeypatch)
    calls = []

    def fake_train(data, model, out, **kw):
        pathlib.Path(out).mkdir(parents=True, exist_ok=True)
        calls.append((pathlib.Path(out).name, kw))
        for step in range(3):
            if kw.get("callback"):
                kw["callback"](step, {})

    monkeypatch.setattr(ladder, "train", fake_train)
    rung = next(r for r in ladder.RUNGS if r.name == "kstep")
    assert rung.train["curriculum_epochs"] > 0 and rung.train["rollout_steps"] > 1
    ladder._train_rung(rung, "data.h5", tmp_path / "kstep", {}, minutes=1.0, max_epochs=7)
    (calib, calib_kw), (run, run_kw) = calls
    assert calib == "calibration" and calib_kw["epochs"] == 1
    assert calib_kw["curriculum_epochs"] == 0  # timed at k = rollout_steps, not k = 1
    assert run == "run" and run_kw["curriculum_epochs"] == rung.train["curriculum_epochs"]
    assert run_kw["epochs"] == 7  # the fake's instant epochs fit max_epochs
    assert not (tmp_path / "kstep" / "calibration").exists()


def test_ensemble_rung_trains_members_like_the_reused_rung(tmp_path, monkeypatch):
    """Member 0 is the reused rung's run; members 1 .. M-1 get its recipe, its epoch count
    and seeds 1 .. M-1; a missing reused run is a clear error."""
    import json

    import pytest

    ladder = _ladder(monkeypatch)
    rung = next(r for r in ladder.RUNGS if r.name == "ensemble")
    assert rung.members > 1 and rung.guards
    calls = []

    def fake_train(data, model, out, **kw):
        calls.append((pathlib.Path(out), kw))

    monkeypatch.setattr(ladder, "train", fake_train)
    with pytest.raises(SystemExit, match=rung.reuse):
        ladder._member_runs(rung, tmp_path, "data.h5", {}, None)
    first = tmp_path / rung.reuse / "run"
    first.mkdir(parents=True)
    (first / "config.json").write_text(json.dumps({"train": {"epochs": 4}}))
    runs = ladder._member_runs(rung, tmp_path, "data.h5", {"test_sims": ["a"]}, None)
    assert runs[0] == first and len(runs) == rung.members
    reused = next(r for r in ladder.RUNGS if r.name == rung.reuse)
    assert reused.train == rung.train  # so the members live beside the reused rung's run
    for seed, (out, kw) in enumerate(calls, start=1):
        assert out == tmp_path / rung.reuse / f"member_{seed}" / "run" == runs[seed]
        assert kw["seed"] == seed and kw["epochs"] == 4 and kw["test_sims"] == ["a"]
        assert {k: kw[k] for k in reused.train} == reused.train  # the same recipe


def test_the_recipes_are_the_ladders_rungs(monkeypatch):
    """README and docs say `thrombojax train`'s default recipe, `outlet`, is the ladder's
    follow_room30_outlet_last rung, `--recipe room` its follow_room30_last rung, `--recipe
    axis` its walk_axis rung, `--recipe history` its history_walk rung, `--recipe rollout` its
    rotation rung, `--recipe robust` its robust rung (the dirspeed_last rungs' recipe): the
    dicts must stay equal."""
    from thrombojax.train.recipes import DEFAULT_RECIPE, recipe

    ladder = _ladder(monkeypatch)
    rungs = {r.name: r for r in ladder.RUNGS}
    assert rungs["walk_axis"].train == recipe("axis")
    assert rungs["history_walk"].train == recipe("history")
    assert rungs["axis_alone"].reuse == "walk_axis" and not rungs["axis_alone"].guards
    assert rungs["rotation"].train == recipe("rollout")
    assert rungs["robust"].train == recipe("robust")
    last = rungs["dirspeed_last"]
    assert {**last.train, "select_by": "last"} == recipe("robust") and last.checkpoint == "last"
    room = rungs["follow_room30_last"]
    assert {**room.train, "select_by": "last"} == recipe("room") and room.checkpoint == "last"
    outlet = rungs["follow_room30_outlet_last"]
    assert {**outlet.train, "select_by": "last"} == recipe("outlet")
    assert outlet.checkpoint == "last" and DEFAULT_RECIPE == "outlet"


def test_members_alone_reports_every_seed(tmp_path, monkeypatch):
    """An ensemble rung also scores each member alone (seed-to-seed spread of the recipe), and
    the table gets one `Seeds:` line with those numbers (experiments/ladder_report.py)."""
    import json

    _ladder(monkeypatch)
    runs = []
    for seed, ratio in ((0, 0.5), (1, 3.0)):
        run = tmp_path / f"m{seed}" / "run"
        run.mkdir(parents=True)
        (run / "config.json").write_text(json.dumps({"train": {"seed": seed}}))
        runs.append((run, ratio))
    ratios = dict((str(r), x) for r, x in runs)

    asked, turned = [], []

    def fake_evaluate(rs, data, guards, n_nodes, which="best", rotations=0):
        (run,) = rs
        asked.append(which)
        turned.append(rotations)
        x = ratios[str(run)]
        return {"mean": {"mse_full": x, "mse_full_cv": 1.0, "final_centroid_r": 10 * x,
                         "mse1_phase": 0.5, "mse1_phase_cv": 1.0, "max_outside": x / 9.2},
                "simulations": {"sim_a": {"final_along_r": x - 1.0}, "sim_b": {}}}

    measure = sys.modules["ladder_eval"]  # imported by the ladder script
    monkeypatch.setattr(measure, "evaluate_runs", fake_evaluate)
    alone = measure.members_alone([r for r, _ in runs], "d.h5", True, None)
    assert [m["seed"] for m in alone] == [0, 1] and asked == ["best", "best"]
    measure.members_alone([r for r, _ in runs], "d.h5", True, None, "last")
    assert asked[2:] == ["last", "last"]  # a rung's checkpoint="last" reaches every member
    measure.members_alone([r for r, _ in runs], "d.h5", True, None, "last", 4)
    assert turned == [0, 0, 0, 0, 4, 4]  # and a rotation rung's copies
    assert [m["mse_full_ratio"] for m in alone] == [0.5, 3.0]
    # the signed final error along the vessel per simulation, where the evaluation has it
    assert [m["final_along_r"] for m in alone] == [{"sim_a": -0.5}, {"sim_a": 2.0}]
    report = sys.modules["ladder_report"]  # imported by the ladder script
    line = report.seed_lines({"ens": {"members_alone": alone}, "single": {}})
    assert "ens" in line and "0.50 / 3.00" in line and "5.00 / 30.00 r" in line
    assert "along the vessel on sim_a (+: ahead) -0.50 / +2.00 r" in line
    assert "sim_b" not in line
    # each member's share outside, to one decimal (5.4 % must not read as the 5 % target)
    assert "max clot outside 5.4 % / 32.6 %" in line
    older = [{k: v for k, v in m.items() if k not in ("final_along_r", "max_outside")}
             for m in alone]
    older_line = report.seed_lines({"ens": {"members_alone": older}})
    assert "along" not in older_line and "outside" not in older_line  # older records
    assert "single" not in line and line.count("\n") == 1


def test_study_size_trains_the_study_model_at_batch_8(tmp_path, monkeypatch):
    """``--size study`` leaves the model config to the study's (no small override), batch 8;
    the default stays the small CPU model at batch 4."""
    ladder = _ladder(monkeypatch)
    calls = []

    def fake_train(data, model, out, **kw):
        calls.append(kw)

    monkeypatch.setattr(ladder, "train", fake_train)
    rung = next(r for r in ladder.RUNGS if r.name == "history_walk")
    ladder._train_rung(rung, "d.h5", tmp_path / "a", {}, 0.0, 5, epochs=2,
                       common=ladder.STUDY_SIZE)
    ladder._train_rung(rung, "d.h5", tmp_path / "b", {}, 0.0, 5, epochs=2)
    study, small = calls
    assert "model_config" not in study and study["batch_size"] == 8
    assert small["model_config"] == ladder.SMALL_MGN and small["batch_size"] == 4
    assert study["noise_walk"] and study["history"] == 2 == small["history"]


def test_transfer_evaluates_every_rung_on_every_simulation_of_the_other_dataset(tmp_path,
                                                                                monkeypatch):
    """--transfer DATA: each rung's models rolled out on all simulations of DATA (the rung's
    own reused / ensemble runs), a per-rung JSON reused on a second call, and a table."""
    import json
    import types

    from dataset_factory import write_good

    ladder = _ladder(monkeypatch)
    other = write_good(tmp_path / "other.h5", n_sims=2)
    out = tmp_path / "ladder"
    calls = []

    def fake_member_runs(rung, out_, data, split, n_nodes, common=None):
        return [out_ / rung.name / "run"] * rung.members

    def fake_evaluate(runs, data, guards, n_nodes=None, names=None, which="best",
                      committee=False, rotations=0):
        calls.append((len(runs), data, guards, names))
        assert rotations == 0  # these rungs roll out no rotated copies
        return {"mean": {"mse1_all": 1.0, "mse1_all_cv": 2.0, "mse1_phase": 1.0,
                         "mse1_phase_cv": 2.0, "mse10": 0.1, "mse_full": 0.5,
                         "mse_full_cv": 1.0, "final_centroid_r": 0.7,
                         "final_centroid_cv_r": 3.0, "max_outside": 0.1,
                         "max_outside_cv": 0.5, "max_correction_r": 0.0, "mse10_cv": 0.2},
                "simulations": {}, "epochs": 3}

    monkeypatch.setattr(ladder, "_member_runs", fake_member_runs)
    monkeypatch.setattr(ladder, "evaluate_runs", fake_evaluate)
    report = sys.modules["ladder_report"]
    monkeypatch.setattr(report, "plot_error_per_step", lambda *a, **k: None)
    for name in ("speed03_guards", "speed03_seeds"):
        (out / name).mkdir(parents=True)
    args = types.SimpleNamespace(dataset="train.h5", nodes=None, title="T")
    results = {"speed03_guards": {"epochs": 3}, "speed03_seeds": {"epochs": 3}}
    text = ladder._transfer(other, results, out, args, {}, {})
    assert calls == [(1, str(other), True, ["sim_0", "sim_1"]),
                     (2, str(other), False, ["sim_0", "sim_1"])]
    assert json.loads((out / "speed03_seeds" / "transfer_other.json").read_text())["epochs"] == 3
    assert "speed03_guards" in text and (out / "transfer_other" / "table.md").is_file()
    assert "| 10.0 % |" in text and "| 50.0 % |" in text  # shares outside to one decimal
    ladder._transfer(other, results, out, args, {}, {})
    assert len(calls) == 2  # reused, not evaluated again


def test_a_rung_trained_on_the_rollout_phase_reads_the_skip_from_the_dataset(tmp_path,
                                                                               monkeypatch):
    """`follow_steady` asks for `skip_frames="dataset"`: the ladder trains it with the
    dataset's own skip_frames attribute (its windows start where rollouts start), and a rung
    without it keeps the TrainConfig default."""
    from dataset_factory import make_simulation

    from thrombojax.io.writer import write_dataset

    ladder = _ladder(monkeypatch)
    data = write_dataset(tmp_path / "d.h5", [make_simulation(f"s{i}", n_frames=6, seed=i)
                                             for i in range(2)],
                         name="tiny", source="tests", skip_frames=3)
    calls = []
    monkeypatch.setattr(ladder, "train", lambda d, m, out, **kw: calls.append(kw))
    rungs = {r.name: r for r in ladder.RUNGS}
    assert rungs["follow_steady"].train["skip_frames"] == "dataset"
    ladder._train_rung(rungs["follow_steady"], str(data), tmp_path / "a", {}, 1.0, 3, epochs=2)
    ladder._train_rung(rungs["follow_nohist"], str(data), tmp_path / "b", {}, 1.0, 3, epochs=2)
    assert calls[0]["skip_frames"] == 3 and calls[0]["history"] == 1
    assert "skip_frames" not in calls[1]


def test_rungs_that_reuse_one_rung_share_its_members(tmp_path, monkeypatch):
    """Two ensemble rungs over the same rung and recipe (guarded and alone) train each seed
    once; a rung with another recipe, and a member an earlier ladder trained in the rung's own
    folder, keep their own."""
    import json

    ladder = _ladder(monkeypatch)
    calls = []

    def fake_train(data, model, out, **kw):
        out = pathlib.Path(out)
        calls.append(out)
        for which in ("best", "last"):
            (out / "checkpoints" / which).mkdir(parents=True)
        (out / "config.json").write_text(json.dumps({"total_steps": 1}))

    monkeypatch.setattr(ladder, "train", fake_train)
    monkeypatch.setattr(ladder, "latest_step", lambda folder: 1 if folder.is_dir() else None)
    monkeypatch.setattr(ladder, "_finished", lambda run, total: True)
    rungs = {r.name: r for r in ladder.RUNGS}
    alone, guarded = rungs["axis_seeds"], rungs["axis_ens_guards"]
    assert alone.reuse == guarded.reuse == "walk_axis" and alone.train == guarded.train
    first = tmp_path / "walk_axis" / "run"
    first.mkdir(parents=True)
    (first / "config.json").write_text(json.dumps({"train": {"epochs": 3}}))
    runs_alone = ladder._member_runs(alone, tmp_path, "data.h5", {}, None)
    runs_guarded = ladder._member_runs(guarded, tmp_path, "data.h5", {}, None)
    assert calls == [tmp_path / "walk_axis" / "member_1" / "run"]  # trained once
    assert runs_alone == runs_guarded == [first, calls[0]]

    other = rungs["dirspeed_last_seeds"]  # its recipe differs from the reused rung's
    assert rungs[other.reuse].train != other.train
    assert ladder._member_folder(other, tmp_path, 1) == tmp_path / other.name / "member_1"
    old = tmp_path / guarded.name / "member_2" / "run"
    old.mkdir(parents=True)  # an earlier ladder's layout is used where it exists
    assert ladder._member_folder(guarded, tmp_path, 2) == old.parent


def test_the_table_names_what_the_simulations_are(tmp_path, monkeypatch):
    """write_reports titles its simulations "held-out" unless told otherwise (models rolled out
    on vessels they trained on are not held out)."""
    _ladder(monkeypatch)
    report = sys.modules["ladder_report"]
    monkeypatch.setattr(report, "plot_error_per_step", lambda *a, **k: None)
    mean = {"mse1_all": 1.0, "mse1_all_cv": 2.0, "mse1_phase": 1.0, "mse1_phase_cv": 2.0,
            "mse10": 0.1, "mse10_cv": 0.2, "mse_full": 0.5, "mse_full_cv": 1.0,
            "final_centroid_r": 0.7, "final_centroid_cv_r": 3.0, "max_outside": 0.1,
            "max_outside_cv": 0.5, "max_correction_r": 0.0}
    results = {"r": {"mean": mean, "simulations": {}, "epochs": 3}}
    report.write_reports(tmp_path, results, title="T", test_sims=["a", "b"], nodes=None)
    first = (tmp_path / "table.md").read_text().splitlines()[0]
    assert first == "# Stability ladder (T, held-out simulations a, b)"
    report.write_reports(tmp_path, results, title="T", test_sims=["a", "b"], nodes=None,
                         sims_kind="training simulations")
    first = (tmp_path / "table.md").read_text().splitlines()[0]
    assert first == "# Stability ladder (T, training simulations a, b)"
    unc = {k: 0.5 for k in ("spearman", "pearson", "temporal_pearson", "calibration",
                             "within_2_spread", "mean_spread", "mean_error")}
    ensemble = {"ens": {"members": 2, "simulations": {"a": {"uncertainty": unc}}}}
    assert "(means over the training simulations)" in report.uncertainty_lines(
        ensemble, "training simulations")
    assert "(means over the held-out simulations)" in report.uncertainty_lines(ensemble)
