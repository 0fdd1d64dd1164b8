"""Dataset files: the HDF5 schema (write, read, validate), importers and summaries."""

from thrombojax.io.hdf5 import (
    FORMAT,
    VERSION,
    Dataset,
    DatasetWriter,
    open_dataset,
    write_dataset,
)
from thrombojax.io.info import describe_dataset
from thrombojax.io.meshio_import import (
    import_abaqus,
    import_mesh_series,
    read_abaqus,
    read_frames,
    read_mesh_series,
)
from thrombojax.io.schema import VESSEL_TOLERANCE, Simulation, validate_simulation

__all__ = [
    "FORMAT",
    "VERSION",
    "VESSEL_TOLERANCE",
    "Dataset",
    "DatasetWriter",
    "Simulation",
    "describe_dataset",
    "import_abaqus",
    "import_mesh_series",
    "open_dataset",
    "read_abaqus",
    "read_frames",
    "read_mesh_series",
    "validate_simulation",
    "write_dataset",
]
