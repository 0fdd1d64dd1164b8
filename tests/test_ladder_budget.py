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
