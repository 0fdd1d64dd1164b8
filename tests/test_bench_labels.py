"""The bench table names each row's configuration: a trained small run is not 'the study' mgn."""

from __future__ import annotations

from thrombojax.eval.bench import bench_markdown, run_config_label


def _row(config, weights):
    return {"model": "mgn", "config": config, "case": "bendvessel", "n_nodes": 977,
            "n_steps": 35, "timed_steps": 5, "extrapolated": True, "compile_s": 1.0,
            "rollout_s": 0.1, "per_step_s": 0.01, "full_length_s": 0.4,
            "speedup_vs_abaqus": 450.0, "weights": weights}


def test_run_config_label_names_what_differs_from_the_study_config():
    from thrombojax.models.registry import config_to_dict, get_config

    study = config_to_dict(get_config("mgn"))
    cfg = {"model": "mgn",
           "train": {"tiny": False, "model_config": {**study, "hidden": 32, "processor_size": 5}}}
    assert run_config_label("demo/run_mgn", cfg) == \
        "run run_mgn (study config with hidden=32, processor_size=5)"
    assert run_config_label("r", {"model": "mgn", "train": {"model_config": study}}) == \
        "run r (study config)"
    tiny = config_to_dict(get_config("mgn", tiny=True))
    assert run_config_label("r", {"model": "mgn", "train": {"tiny": True, "model_config": tiny}}) \
        == "run r (tiny config)"


def test_bench_table_has_a_config_column():
    result = {"results": [_row("study config", "random init"),
                          _row("run run_mgn (hidden=32)", "trained")],
              "environment": {"device": "cpu"}, "note": "n"}
    lines = bench_markdown(result).splitlines()
    header = next(ln for ln in lines if ln.startswith("| model"))
    assert header.split("|")[2].strip() == "config"
    rows = [ln for ln in lines if ln.startswith("| mgn")]
    assert [r.split("|")[2].strip() for r in rows] == ["study config", "run run_mgn (hidden=32)"]
