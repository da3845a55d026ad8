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


def check_output_path(path: str | os.PathLike[str]) -> Path:
    """Raise :class:`DataFormatError` unless ``path`` can be written as a file (its folder exists)."""
    target = Path(path)
    if not target.parent.is_dir():
        raise DataFormatError(f"output folder '{target.parent}' does not exist")
    if target.is_dir():
        raise DataFormatError(f"output path '{target}' is a folder")
    return target


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, else remove it."""
    target = check_output_path(path)
    parent = target.parent
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
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


__all__ = ["atomic_output", "check_output_path", "write_atomic", "write_folder_atomic"]
