"""Dataset files: the HDF5 schema (write, read, validate), importers and summaries.

Importers: :mod:`~thrombojax.io.meshio_import` (VTU/VTK/XDMF frames, ``.pvd`` and XDMF
time-series files via :mod:`~thrombojax.io.series_file`) and :mod:`~thrombojax.io.abaqus`
(``.inp`` + per-frame coordinates, :mod:`~thrombojax.io.frames`).
"""

from thrombojax.io.abaqus import import_abaqus, read_abaqus
from thrombojax.io.hdf5 import (
    FORMAT,
    VERSION,
    Dataset,
    DatasetWriter,
    open_dataset,
    write_dataset,
)
from thrombojax.io.info import describe_dataset
from thrombojax.io.meshio_import import import_mesh_series, read_frames, read_mesh_series
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
