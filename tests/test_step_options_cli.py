"""The step's length options on the command line, all in one training (each option's own tests,
without a training, are in its module: test_clearance, test_clot_shape, test_outlet_features,
test_section, test_vessel_axis, test_follow_axis, test_lateral_hold). Every option reaches the
run's ``TrainConfig``, its length the run config in scaled units, and the reloaded step has it,
so the step rolls out as it trained."""

import pytest

# (flag, value, TrainConfig field, the run config's length and the step attribute that holds it)
LENGTHS = [
    ("--clearance-features", 1.0, "clearance_features", "clearance_radius"),
    ("--shape-features", 1.0, "shape_features", "shape_radius"),
    ("--outlet-features", 2.0, "outlet_features", "outlet_radius"),
    ("--section-features", 1.0, "section_features", "section_radius"),
    ("--axis-features", 3.0, "axis_features", "axis_radius"),
    ("--follow-axis", 3.0, "follow_axis", "prior_radius"),
]


def test_cli_trains_with_every_length_option_and_reloads_the_step(tmp_path):
    from dataset_factory import train_tiny_cli

    from thrombojax.train.state import load_trained

    flags = [str(x) for flag, value, _, _ in LENGTHS for x in (flag, value)]
    _, run = train_tiny_cli(tmp_path, *flags, "--lateral-hold", "1.5", n_nodes=80)
    loaded = load_trained(run)
    for flag, value, field, radius in LENGTHS:
        assert getattr(loaded.run.train, field) == value, flag
        assert loaded.config[radius] > 0, flag
        assert getattr(loaded.step, radius) == pytest.approx(loaded.config[radius]), flag
    # the hold's length, in the same scaled units (1.5 vessel radii against the prior's 3)
    assert loaded.run.train.lateral_hold == 1.5
    assert loaded.step.lateral_radius == pytest.approx(0.5 * loaded.config["prior_radius"])
