"""Atomic file output, for every file the package writes.

Everything is written to a temporary file (or folder) beside its target and renamed into place, so
an interrupted or failing write never leaves a partial file and never destroys the previous
version of the target.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path

from fhnn.errors import DataFormatError


def check_writable_folder(folder: str | os.PathLike[str]) -> Path:
    """Raise :class:`DataFormatError` unless ``folder`` is an existing folder this process may
    create files in (checked before any work, so a long computation does not end in a refusal)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DataFormatError(f"output folder '{folder}' is a file, not a folder")
    if not folder.is_dir():
        raise DataFormatError(f"output folder '{folder}' does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise DataFormatError(f"output folder '{folder}' is not writable")
    return folder


def check_output_path(path: str | os.PathLike[str]) -> Path:
    """Raise :class:`DataFormatError` unless ``path`` can be written as a file: its folder exists
    and is writable, and the path is not a folder or a read-only file."""
    target = Path(path)
    check_writable_folder(target.parent)
    if target.is_dir():
        raise DataFormatError(f"output path '{target}' is a folder")
    if target.exists() and not os.access(target, os.W_OK):
        raise DataFormatError(f"output file '{target}' is read-only")
    return target


def _file_mode() -> int:
    """``0o666`` less the process's umask: the mode an ordinary new file gets."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, else remove it."""
    target = check_output_path(path)
    parent = target.parent
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise DataFormatError(f"cannot write '{target}': {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        os.chmod(tmp, _file_mode())  # mkstemp makes 0600 files; the target gets the usual mode
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def write_atomic(path: str | os.PathLike[str], data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8) to ``path`` through :func:`atomic_output`; returns the path."""
    with atomic_output(path) as tmp:
        if isinstance(data, str):
            tmp.write_text(data, encoding="utf-8")
        else:
            tmp.write_bytes(data)
    return Path(path)


def write_folder_atomic(folder: str | os.PathLike[str], files: Mapping[str, bytes]) -> Path:
    """Write ``files`` (relative path → bytes) as the folder ``folder``, replacing it whole: the
    files go into a hidden temporary folder beside it, which is then renamed into place."""
    folder = Path(folder)
    tmp = folder.with_name(f".{folder.name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for rel, data in files.items():
        target = tmp / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    shutil.rmtree(folder, ignore_errors=True)
    os.replace(tmp, folder)
    return folder


__all__ = [
    "atomic_output",
    "check_output_path",
    "check_writable_folder",
    "write_atomic",
    "write_folder_atomic",
]
