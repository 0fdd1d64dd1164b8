"""Bends whose shape is drawn per simulation (``Preset.leg_out_range`` and its siblings)."""

import dataclasses

import numpy as np
import pytest

from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import open_dataset
from thrombojax.sim import generate, geometry, presets
from thrombojax.sim.cases import build_case, build_vessel
from thrombojax.types import NodeType

RANGES = {"leg_out_range": (2.5, 3.5), "bend_radius_range": (2.2, 3.0),
          "bend_angle_range": (60.0, 120.0)}
TINY = presets.get_preset("bendvessel-tiny")
SHAPES = dataclasses.replace(TINY, name="shapes-tiny", batch_size=1, **RANGES)


def test_each_simulation_draws_its_own_shape_within_the_ranges():
    drawn = [build_vessel(SHAPES, i, 0)[1] for i in range(4)]
    for field, key in (("leg_out_range", "leg_out"), ("bend_radius_range", "bend_radius"),
                       ("bend_angle_range", "bend_angle_deg")):
        values = [a[key] for a in drawn]
        low, high = RANGES[field]
        assert all(low <= v <= high for v in values)
        assert len(set(values)) == 4  # a new value per simulation
    again = build_vessel(SHAPES, 2, 0)
    assert again[1] == drawn[2]  # reproducible from (seed, index)
    first = np.asarray(build_vessel(SHAPES, 2, 0)[0].points)
    assert np.array_equal(np.asarray(again[0].points), first)
    assert build_vessel(SHAPES, 2, 1)[1] != drawn[2]  # another seed, another shape


def test_a_preset_without_ranges_keeps_its_one_tube():
    cl0, a0 = build_vessel(TINY, 0, 0)
    cl3, a3 = build_vessel(TINY, 3, 5)
    assert (a0["leg_out"], a0["bend_radius"], a0["bend_angle_deg"]) == (
        TINY.leg_out, TINY.bend_radius, TINY.bend_angle_deg)
    assert a0 == a3 and np.array_equal(np.asarray(cl0.points), np.asarray(cl3.points))
    # the clot's draws are those of the stream [seed, index] whatever the vessel stream does
    assert build_case(SHAPES, 1, 0).attrs["roll_deg"] == build_case(TINY, 1, 0).attrs["roll_deg"]


@pytest.mark.parametrize("change, match", [
    ({"batch_size": 2}, "batch_size 1"),
    ({"kind": "tortuous"}, "kind 'bend'"),
    ({"bend_angle_range": (120.0, 60.0)}, "bend_angle_range"),
    ({"leg_out_range": (0.0, 3.0)}, "leg_out_range"),
])
def test_bad_shape_ranges_are_refused(change, match):
    with pytest.raises(ConfigError, match=match):
        dataclasses.replace(SHAPES, **change)


def test_a_batch_of_different_vessels_is_refused():
    cases = [build_case(SHAPES, i, 0) for i in (0, 1)]
    with pytest.raises(ConfigError, match="different vessels"):
        generate.compile_cases(SHAPES, cases)


def test_generated_shapes_share_the_node_count_and_differ_in_their_walls(tmp_path):
    path = generate.generate_dataset(SHAPES, tmp_path / "shapes.h5", n_sims=2, seed=0,
                                     progress=False)
    ds = open_dataset(path)
    sims = [ds[name] for name in ds]
    assert len(sims) == 2
    a, b = sims
    assert a.positions.shape[1:] == b.positions.shape[1:]
    wall = a.node_type == NodeType.VESSEL
    unturned = [np.asarray(s.positions[0], np.float64)
                @ geometry.rotation_matrix(SHAPES.rotation_axis, s.attrs["rotation_deg"])
                for s in sims]  # the output rotation undone: the vessels' own shapes
    assert np.abs(unturned[0][wall] - unturned[1][wall]).max() > 0.5
    for sim in sims:
        assert RANGES["bend_angle_range"][0] <= sim.attrs["bend_angle_deg"] <= 120.0
        assert np.all(np.isfinite(sim.positions))
