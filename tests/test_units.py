"""Units: a run trained on one length unit refuses a dataset in another."""

from __future__ import annotations

import pytest
from dataset_factory import make_simulation

from thrombojax.errors import ConfigError
from thrombojax.io.hdf5 import open_dataset, write_dataset
from thrombojax.units import check_units, dataset_units


def test_check_units(tmp_path):
    mm = open_dataset(write_dataset(tmp_path / "mm.h5", [make_simulation()], name="a",
                                    source="t", units="mm"))
    assert dataset_units(mm) == "mm"
    check_units({"units": "mm"}, mm, run_dir="run", dataset_path="mm.h5")
    check_units({}, mm, run_dir="run", dataset_path="mm.h5")  # an older run: nothing recorded
    with pytest.raises(ConfigError, match="mm.h5: coordinates are in 'mm', but the run run was "
                       "trained on 'm'"):
        check_units({"units": "m"}, mm, run_dir="run", dataset_path="mm.h5")
