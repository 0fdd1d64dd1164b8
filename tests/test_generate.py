"""Dataset generation: file layout, determinism, vmap == single run, CLI, plot."""

import numpy as np
import pytest

from thrombojax.cli import main
from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import open_dataset
from thrombojax.sim import generate, presets
from thrombojax.types import NodeType


@pytest.fixture(scope="module")
def bend_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "bv.h5"
    generate.generate_dataset("bendvessel-tiny", out, n_sims=2, seed=3, plot=True, progress=False)
    return out


def test_file_layout(bend_file):
    preset = presets.get_preset("bendvessel-tiny")
    ds = open_dataset(bend_file)
    assert ds.names == ["bendvessel-tiny_000", "bendvessel-tiny_001"]
    assert ds.attrs["generator_config"]  # the preset is recorded
    for i, name in enumerate(ds.names):
        sim = ds[name]
        n_clot = int(np.sum(sim.node_type == NodeType.CLOT))
        assert sim.positions.shape == (preset.n_frames + 1, sim.n_nodes, 3)
        assert sim.positions.dtype == np.float32
        assert sim.clot_cells.max() < n_clot <= sim.wall_cells.min()
        assert sim.attrs["rotation_deg"] == pytest.approx(10.0 * i)
        assert sim.attrs["seed"] == 3 and sim.attrs["solver_wall_time_s"] > 0
    assert bend_file.with_suffix(".png").stat().st_size > 10_000


def test_same_seed_same_arrays_and_vmap_equals_single(bend_file, tmp_path):
    again = tmp_path / "again.h5"
    generate.generate_dataset("bendvessel-tiny", again, n_sims=2, seed=3, progress=False)
    a, b = open_dataset(bend_file), open_dataset(again)
    for name in a.names:
        np.testing.assert_array_equal(a[name].positions, b[name].positions)
        np.testing.assert_array_equal(a[name].clot_cells, b[name].clot_cells)
    single = generate.simulate("bendvessel-tiny", 1, seed=3)  # not batched
    np.testing.assert_allclose(single.positions, a["bendvessel-tiny_001"].positions, atol=5e-3)


def test_other_seed_differs(bend_file, tmp_path, capsys):
    out = tmp_path / "cli.h5"
    assert (
        main(
            [
                "generate",
                "bendvessel-tiny",
                "--out",
                str(out),
                "--sims",
                "1",
                "--seed",
                "4",
                "--quiet",
                "--plot",
            ]
        )
        == 0
    )
    assert f"wrote {out.with_suffix('.png')}" in capsys.readouterr().out
    other = open_dataset(out)["bendvessel-tiny_000"]
    ref = open_dataset(bend_file)["bendvessel-tiny_000"]
    assert other.attrs["oversize"] != ref.attrs["oversize"]
    assert not np.allclose(other.positions, ref.positions)


def test_bad_arguments(tmp_path, capsys):
    with pytest.raises(ConfigError, match="known presets"):
        presets.get_preset("nope")
    with pytest.raises(ConfigError):
        generate.generate_dataset("bendvessel-tiny", tmp_path / "x.h5", n_sims=0)
    assert main(["generate", "nope", "--out", str(tmp_path / "y.h5")]) == 2
    assert "unknown solver preset" in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists()


def test_full_presets_have_the_study_shapes():
    bv, ce = presets.get_preset("bendvessel"), presets.get_preset("clotentry")
    assert (bv.n_sims, bv.n_frames, bv.reference_wall_time_s) == (20, 40, 180.0)
    assert (ce.n_sims, ce.n_frames, ce.reference_wall_time_s) == (10, 200, 1500.0)
    n_bv = (bv.clot_cross + 1) ** 2 * (bv.clot_cells + 1) + bv.wall_rings * bv.wall_around
    n_ce = (ce.clot_cross + 1) ** 2 * (ce.clot_cells + 1) + ce.wall_rings * ce.wall_around
    assert n_bv == 977 and abs(n_ce - 27_000) < 500


def test_presets_record_kind_and_skip_frames(tmp_path):
    """The dataset says which frames rollouts skip: the study's share of its simulation."""
    from thrombojax import study

    assert [presets.get_preset(n).skip_frames for n in
            ("bendvessel", "clotentry", "bendvessel-tiny", "clotentry-tiny")] == [5, 40, 1, 2]
    out = generate.generate_dataset("bendvessel-tiny", tmp_path / "t.h5", n_sims=1,
                                    progress=False)
    from thrombojax.io.hdf5 import open_dataset

    ds = open_dataset(out)
    assert study.dataset_kind(ds) == "bendvessel" and study.skip_frames(ds) == 1
