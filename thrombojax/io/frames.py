"""Per-frame node coordinates on disk (the Abaqus ``.odb`` export format) and frame-file lists.

``frames`` is one of:

- one ``.npy`` file holding a float array ``[T, N, 3]``;
- a folder of per-frame files ``frame_0000.npy``, ``frame_0001.npy``, ... (each ``[N, 3]``) or
  ``frame_0000.csv``, ... (natural file-name order; any names work, one suffix per folder).
  A CSV has one row per node, comma- or whitespace-separated, an optional header line, and
  either 3 columns ``x, y, z`` in the mesh's node order or 4 columns ``label, x, y, z``
  (Abaqus node labels, any row order).

With ``keep`` (nodes kept from the mesh, e.g. without a rigid body's reference node), a frame may
list all mesh nodes (the other rows are dropped) or only the kept ones.

:func:`source_name` is the default simulation name of every importer: a folder's name, a file's
stem, or for a glob the name of the folder holding the files.
"""

from __future__ import annotations

import glob
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from thrombojax.io.schema import natural_key, simulation_error

__all__ = ["list_frame_files", "read_frames", "source_name"]


def source_name(source: str | os.PathLike | Sequence) -> str:
    """Default simulation name of a frames source: folder name, file stem, or glob's folder."""
    if isinstance(source, list | tuple):
        return Path(source[0]).resolve().parent.name if source else "simulation"
    path = Path(source)
    if path.is_dir():
        return path.resolve().name
    if glob.has_magic(str(source)):
        return path.parent.resolve().name or "simulation"
    return path.stem or "simulation"


def list_frame_files(source: str | os.PathLike | Sequence, suffixes: Sequence[str]) -> list[Path]:
    """Resolve a folder, a glob pattern or a list of files into frame files in natural order."""
    if isinstance(source, list | tuple):
        files = [Path(f) for f in source]
    elif Path(source).is_dir():
        files = [p for p in Path(source).iterdir() if p.suffix.lower() in suffixes]
    elif glob.has_magic(str(source)):
        files = [Path(f) for f in glob.glob(str(source))]
    elif Path(source).is_file():
        files = [Path(source)]
    else:
        raise FileNotFoundError(f"{source}: no such folder, file or matching glob")
    files = sorted(files, key=lambda p: natural_key(str(p)))
    if not files:
        raise simulation_error(source, None, "frames", f"no frame files ({'/'.join(suffixes)})")
    kinds = {p.suffix.lower() for p in files}
    if len(kinds) > 1:
        raise simulation_error(source, None, "frames", f"mixed frame formats {sorted(kinds)}")
    return files


def _read_csv(path: Path, name: str) -> np.ndarray:
    """Read one CSV frame; a first line that is not all numbers is a header."""
    try:
        with open(path) as f:
            head = f.readline()
        delimiter = "," if "," in head else None
        tokens = [t for t in re.split(r"[,\s]+", head.strip()) if t]
        skip = 0 if all(_is_number(t) for t in tokens) else 1
        return np.loadtxt(path, delimiter=delimiter, skiprows=skip, ndmin=2, dtype=np.float64)
    except ValueError as err:  # includes UnicodeDecodeError
        raise simulation_error(path, name, "positions", f"bad CSV: {err}") from err


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def read_frames(
    frames: str | os.PathLike, *, n_nodes: int, labels: np.ndarray | None = None,
    name: str = "?", keep: np.ndarray | None = None,
) -> np.ndarray:
    """Read per-frame node coordinates in the format of the module docstring.

    Args:
        frames: a ``[T, N, 3]`` ``.npy`` file or a folder of per-frame ``.npy`` / ``.csv`` files.
        n_nodes: N, the mesh's node count (each frame must match).
        labels: ``[N]`` Abaqus node labels in mesh order (needed for 4-column CSV files).
        name: simulation name (for messages).
        keep: optional ``[N]`` bool, the mesh nodes to return (module docstring).
    Returns:
        ``[T, N, 3]`` float32 positions (``[T, keep.sum(), 3]`` with ``keep``).
    """
    if keep is not None and not np.asarray(keep).all():
        keep = np.asarray(keep, bool)
        n_keep = int(keep.sum())
        allowed = (n_nodes, n_keep)
        pos = _read_all(Path(frames), allowed, labels, name, keep)
        return pos[:, keep] if pos.shape[1] == n_nodes else pos
    return _read_all(Path(frames), (n_nodes,), labels, name, None)


def _read_all(frames: Path, allowed: tuple[int, ...], labels, name: str, keep) -> np.ndarray:
    """Frames with one of the ``allowed`` node counts (all frames the same count)."""
    expect = " or ".join(map(str, allowed))
    if frames.is_file() and frames.suffix.lower() == ".npy":
        arr = _load_npy(frames, name)
        if arr.ndim != 3 or arr.shape[1] not in allowed or arr.shape[2] != 3:
            raise simulation_error(frames, name, "positions", f"shape {arr.shape}, expected "
                                   f"[frames, {expect}, 3]")
        return arr.astype(np.float32)
    if not frames.is_dir():
        raise FileNotFoundError(f"{frames}: expected a [T, N, 3] .npy file or a folder of frames")
    files = list_frame_files(frames, (".npy", ".csv"))
    out = None
    for t, path in enumerate(files):
        arr = _load_npy(path, name) if path.suffix.lower() == ".npy" else _read_csv(path, name)
        if arr.ndim == 2 and arr.shape[1] == 4 and path.suffix.lower() == ".csv":
            wanted = labels if keep is None or labels is None or len(arr) == len(labels) \
                else labels[keep]
            arr = _order_by_label(arr, wanted, path, name)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise simulation_error(path, name, "positions", f"shape {arr.shape}, expected [N, 3]")
        count = allowed if out is None else (out.shape[1],)
        if arr.shape[0] not in count:
            raise simulation_error(path, name, "positions", f"{arr.shape[0]} nodes, but the "
                                   f"mesh has {' or '.join(map(str, count))}")
        if out is None:
            out = np.empty((len(files), arr.shape[0], 3), np.float32)
        out[t] = arr
    return out


def _load_npy(path: Path, name: str) -> np.ndarray:
    try:
        arr = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError) as err:
        raise simulation_error(path, name, "positions", f"cannot read .npy: {err}") from err
    if arr.dtype.kind not in "iuf":
        raise simulation_error(path, name, "positions", f"wrong dtype {arr.dtype}")
    return arr


def _order_by_label(arr: np.ndarray, labels: np.ndarray | None, path: Path, name: str):
    if labels is None:
        raise simulation_error(path, name, "positions", "4-column CSV (label, x, y, z) but the "
                               ".inp node labels are unknown")
    got = arr[:, 0].astype(np.int64)
    order = np.argsort(got)
    pos = np.searchsorted(got[order], labels)
    pos = np.minimum(pos, len(got) - 1)
    found = got[order][pos] == labels
    if not found.all() or len(got) != len(labels) or len(np.unique(got)) != len(got):
        missing = labels[~found][:3].tolist()
        raise simulation_error(path, name, "positions", f"node labels do not match the .inp "
                               f"({len(got)} rows for {len(labels)} nodes; missing e.g. {missing})")
    return arr[order[pos], 1:]
