"""Output safety: one rule for every file thrombojax writes.

1. Never write over an input: :func:`check_target` refuses a target that is (or links to) one of
   the command's input files.
2. Never replace an existing output unless asked (``force=True``, the CLI's ``--force``).
3. Write atomically: :func:`atomic_path` hands out a temporary path beside the target (same
   folder, so the final ``os.replace`` is atomic) and renames it onto the target only when the
   block exits cleanly; on an exception the temporary is removed. A temporary left by a killed
   process carries that process's id and is removed by :func:`clean_temporaries` on the next run
   in that folder.
4. File names built from simulation names cannot collide or escape the output folder
   (:func:`safe_stem`, :func:`safe_stems`): characters outside ``[A-Za-z0-9_.-]``, a leading or
   trailing dot, Windows reserved names (``CON``, ``NUL``, ``COM1``, ...) and names that differ
   only in case are rewritten, with a short hash of the original name so that no two names map
   to one file. Names are never passed through ``Path.with_suffix`` (``flow_0.5`` and
   ``flow_1.5`` stay two files).
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import os
import re
import shutil
import time
import uuid
from collections.abc import Iterable, Iterator
from pathlib import Path

from thrombojax.errors import OutputError

__all__ = [
    "TEMP_TAG",
    "safe_stem",
    "safe_stems",
    "check_target",
    "check_targets",
    "refuse_targets",
    "atomic_path",
    "atomic_write_text",
    "clean_temporaries",
    "remove_atomically",
    "input_files",
    "temp_path",
    "fresh_owned_folder",
]

TEMP_TAG = ".tjxtmp-"
# any tail after the tag: writers that derive a name from a temporary (a temporary of a
# temporary, PillowWriter's added ".gif") leave temporaries too (issue 14 kill -9 trials)
_TEMP_RE = re.compile(r"^\..*\.tjxtmp-(\d+)-[0-9a-f]{8}(\..*)?$")
_RESERVED = {"CON", "PRN", "AUX", "NUL", "CONIN$", "CONOUT$"} | {
    f"{p}{i}" for p in ("COM", "LPT") for i in "0123456789¹²³"
}
_MAX_STEM = 120


def _digest(name: str) -> str:
    return hashlib.sha1(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]


def safe_stem(name: str) -> str:
    """A file-name stem for a simulation name, safe on POSIX and Windows.

    The name is kept when it is already safe (``[A-Za-z0-9_.-]``, no leading / trailing dot,
    not a Windows reserved name, at most 120 characters); otherwise offending characters become
    ``_`` and ``-<8 hex digits of sha1(name)>`` is appended, so two different names never give
    the same stem (``..`` -> ``_-<hash>``, ``a/b`` -> ``a_b-<hash>``).
    """
    name = str(name)
    stem = re.sub(r"[^A-Za-z0-9_.\-]", "_", name).strip(". ")
    if stem.split(".")[0].upper() in _RESERVED:
        stem = "_" + stem
    stem = stem[:_MAX_STEM] or "_"
    return stem if stem == name else f"{stem}-{_digest(name)}"


def safe_stems(names: Iterable[str]) -> dict[str, str]:
    """:func:`safe_stem` of each name, also unique when compared without case.

    On case-insensitive file systems (Windows, macOS) ``Flow`` and ``flow`` would share files;
    every name of such a group gets its hash appended.
    """
    stems = {str(n): safe_stem(n) for n in names}
    groups: dict[str, list[str]] = {}
    for name, stem in stems.items():
        groups.setdefault(stem.casefold(), []).append(name)
    for members in groups.values():
        if len(members) > 1:
            for name in members:
                if not stems[name].endswith(_digest(name)):
                    stems[name] = f"{stems[name]}-{_digest(name)}"
    return stems


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_target(
    target: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (), force: bool = False,
    what: str = "output",
) -> Path:
    """Refuse a target that is an input, or that exists without ``force``.

    Args:
        target: the file (or folder) about to be written.
        inputs: the command's input files; a target that is one of them (same path, a link to
            it, or a hard link) is always refused, even with ``force``.
        force: allow replacing an existing output (never an input).
        what: what the target is, for the message (e.g. ``"dataset"``).
    Returns:
        ``target`` as a :class:`~pathlib.Path`.
    Raises:
        OutputError: naming the target and the reason.
    """
    target = Path(target)
    for src in inputs:
        src = Path(src)
        if target.resolve() == src.resolve() or _same_file(target, src):
            raise OutputError(f"{target}: the {what} would overwrite the input {src}; "
                              "choose another output name or folder")
    if target.exists() and not force:
        raise OutputError(f"{target}: {what} already exists; pass --force to replace it")
    return target


def check_targets(targets: Iterable[str | os.PathLike], **kwargs) -> list[Path]:
    """:func:`check_target` on every target (before anything is written), plus no duplicates."""
    out = [check_target(t, **kwargs) for t in targets]
    seen: dict[str, Path] = {}
    for path in out:
        key = str(path.resolve()).casefold()
        if key in seen:
            raise OutputError(f"{path}: two outputs of this command share this file name "
                              f"({seen[key].name}, {path.name})")
        seen[key] = path
    return out


def refuse_targets(parser, targets: Iterable, **kwargs) -> list[Path]:
    """:func:`check_targets` for a script's ``argparse`` options: ``None`` targets (options not
    given) are skipped, and a refusal becomes ``parser.error`` (usage, exit status 2).

    Args:
        parser: the script's :class:`argparse.ArgumentParser`.
        targets: the output paths, ``None`` where the option was not given.
        **kwargs: ``inputs``, ``force`` and ``what`` of :func:`check_target`.
    Returns:
        The given targets as :class:`~pathlib.Path`.
    """
    try:
        return check_targets([t for t in targets if t is not None], **kwargs)
    except OutputError as err:
        parser.error(str(err))
        raise  # parser.error exits; a parser that returns still refuses


def input_files(sources: Iterable) -> list[Path]:
    """The files behind input arguments: files, the files of folders (one level), glob matches,
    lists of files. Used to refuse an output that would replace one of them."""
    out: list[Path] = []
    for src in sources:
        if isinstance(src, list | tuple):
            out += input_files(src)
        elif Path(src).is_dir():
            with contextlib.suppress(OSError):
                out += [p for p in Path(src).iterdir() if p.is_file()]
        elif glob.has_magic(str(src)):
            out += [Path(f) for f in glob.glob(str(src))]
        else:
            out.append(Path(src))
    return out


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _pid_alive(pid: int, path: Path) -> bool:
    if pid == os.getpid():
        return True
    if os.name == "nt":  # os.kill(pid, 0) would terminate it there: go by age instead
        try:
            return time.time() - path.stat().st_mtime < 86400
        except OSError:
            return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True
    return True


def clean_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Remove thrombojax temporaries in ``folder`` left by processes that no longer run
    (on Windows: older than a day, since a process id cannot be probed safely there).

    Returns:
        The removed paths.
    """
    folder = Path(folder)
    removed = []
    if not folder.is_dir():
        return removed
    with contextlib.suppress(OSError):
        for entry in folder.iterdir():
            m = _TEMP_RE.match(entry.name)
            if m and not _pid_alive(int(m.group(1)), entry):
                _remove(entry)
                removed.append(entry)
    return removed


def remove_atomically(path: str | os.PathLike) -> None:
    """Remove ``path`` (a file, link or folder tree) so that no reader ever sees it half-removed.

    It is first renamed to a temporary beside it (one atomic step), then deleted: a process
    killed during the deletion leaves only that temporary, which :func:`clean_temporaries`
    removes on the next run in the folder (as it does here, first). A missing ``path`` is fine.
    """
    path = Path(path)
    if not (path.exists() or path.is_symlink()):
        clean_temporaries(path.parent)
        return
    doomed = temp_path(path, suffix="")  # also clears the temporaries of killed removals
    path.rename(doomed)
    _remove(doomed)


def temp_path(target: str | os.PathLike, suffix: str | None = None) -> Path:
    """A fresh temporary name beside ``target`` (hidden, tagged with this process's id, ending
    in ``suffix``, default the target's suffix); stale temporaries of dead processes in that
    folder are removed first."""
    target = Path(target)
    clean_temporaries(target.parent)
    suffix = target.suffix if suffix is None else suffix
    return target.with_name(f".{target.name}{TEMP_TAG}{os.getpid()}-{uuid.uuid4().hex[:8]}"
                            f"{suffix}")


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; rename it onto ``target`` on a clean exit.

    The temporary keeps the target's suffix (writers that pick a format from the suffix, such
    as matplotlib, meshio or Pillow, work unchanged) and may be a file or a folder. An
    existing target is replaced (check it first with :func:`check_target`). Stale temporaries
    of dead processes in the same folder are removed first.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(target)
    try:
        yield tmp
        if not tmp.exists():
            raise OutputError(f"{target}: the writer produced no file")
        if tmp.is_dir() and target.is_dir():
            old = target.with_name(f".{target.name}{TEMP_TAG}{os.getpid()}-"
                                   f"{uuid.uuid4().hex[:8]}")
            os.replace(target, old)
            os.replace(tmp, target)
            _remove(old)
        else:
            if tmp.is_file():
                with open(tmp, "rb+") as f:  # on disk before the rename makes it visible
                    os.fsync(f.fileno())
            os.replace(tmp, target)
    except BaseException:
        _remove(tmp)
        raise


def atomic_write_text(target: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``target`` atomically (see :func:`atomic_path`)."""
    target = Path(target)
    with atomic_path(target) as tmp:
        tmp.write_text(text)
    return target


def fresh_owned_folder(folder: str | os.PathLike, owner: str) -> Path:
    """Empty ``folder`` for a command that rewrites it whole (e.g. the demo), safely.

    A folder this owner made before (it holds the marker ``.thrombojax-<owner>``) is removed
    and re-created; an empty or missing folder is created; any other existing folder is
    refused with :class:`~thrombojax.errors.OutputError` (it may hold a user's data).
    """
    folder = Path(folder)
    marker = f".thrombojax-{owner}"
    if folder.exists():
        if not folder.is_dir():
            raise OutputError(f"{folder}: exists and is not a folder")
        if any(folder.iterdir()) and not (folder / marker).is_file():
            raise OutputError(f"{folder}: exists and was not written by thrombojax {owner}; "
                              "choose a new or empty output folder")
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    (folder / marker).write_text(f"written by thrombojax {owner}; its next run replaces this "
                                 "whole folder\n")
    return folder
