"""Atomic file output, for every file the package writes.

Everything is written to a temporary file (or folder) beside its target and renamed into place, so
an interrupted or failing write never leaves a partial file and never destroys the previous
version of the target. Files that must change together (a training checkpoint: weights, optimiser
state and ``run.json``) go through :func:`commit_files`, a small journal: a process killed at any
point leaves, once :func:`recover_files` has run, either every old version or every new one.
(Renames protect against killed processes and failed writes, not against power loss: nothing is
fsynced.)
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator, Mapping
from glob import escape as glob_escape
from pathlib import Path

from fhnn.errors import ConfigError, DataFormatError


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


def check_new_folder(folder: str | os.PathLike[str]) -> Path:
    """Raise :class:`DataFormatError` unless ``folder`` is an existing writable folder, or can be
    created as one (it does not exist and its parent is a writable folder)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DataFormatError(f"output '{folder}' exists and is not a folder")
    return check_writable_folder(folder if folder.is_dir() else folder.parent)


def check_input_file(path: str | os.PathLike[str], kind: str) -> Path:
    """``path`` as a :class:`Path` if it is an existing file; else :class:`DataFormatError`
    saying it is missing or a folder (``kind``: what the file should be, e.g. "a data file")."""
    path = Path(path)
    if not path.exists():
        raise DataFormatError(f"{path}: no such file")
    if path.is_dir():
        raise DataFormatError(f"{path}: is a folder, not {kind}")
    return path


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
    for stale in parent.glob(f".{glob_escape(target.name)}.*.tmp"):  # left by a killed writer
        stale.unlink(missing_ok=True)
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
    except OSError as exc:  # a full disk, a quota: the previous version of the target is intact
        raise DataFormatError(f"cannot write '{target}': {exc.strerror or exc}") from None
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


#: The journal of :func:`commit_files`: present only between its commit point and its last rename.
JOURNAL = ".commit.json"


def _pending(folder: Path, name: str) -> Path:
    return folder / f".{name}.pending"


def recover_files(folder: str | os.PathLike[str]) -> None:
    """Finish or undo a :func:`commit_files` that a killed process left half done: with a journal,
    rename its remaining pending files into place (the commit had happened); without one, remove
    pending files (it had not). Does nothing in a clean folder."""
    folder = Path(folder)
    journal = folder / JOURNAL
    pending = sorted(folder.glob(".*.pending"))
    if not journal.exists() and not pending:
        return
    try:
        if journal.exists():
            for name in json.loads(journal.read_text(encoding="utf-8")):
                if _pending(folder, name).exists():
                    os.replace(_pending(folder, name), folder / name)
            journal.unlink()
        for path in pending:  # those the journal did not rename: an uncommitted write
            path.unlink(missing_ok=True)
    except (OSError, ValueError) as exc:
        raise DataFormatError(
            f"{folder}: an interrupted checkpoint write cannot be completed ({exc}); make the folder "
            "writable and retry"
        ) from None


def commit_files(folder: str | os.PathLike[str], writers: Mapping[str, Callable[[Path], None]]) -> None:
    """Replace the files ``writers`` names in ``folder`` together: ``writers[name](tmp)`` writes the
    new version of ``folder/name`` to the path ``tmp``.

    Every new version is written to a pending file first (a failure there — a full disk — leaves
    the old versions in place and raises); then the journal is written (the commit point); then the
    pending files are renamed into place and the journal removed. :func:`recover_files` completes
    or undoes a commit a kill interrupted; it runs here first and wherever a run is loaded."""
    folder = Path(folder)
    recover_files(folder)
    try:
        for name, write in writers.items():
            try:
                with atomic_output(_pending(folder, name)) as tmp:
                    write(tmp)
            except DataFormatError as exc:  # name the file the user knows, not the pending one
                raise DataFormatError(
                    str(exc).replace(str(_pending(folder, name)), str(folder / name))
                ) from None
    except BaseException:
        for name in writers:
            _pending(folder, name).unlink(missing_ok=True)
        raise
    write_atomic(folder / JOURNAL, json.dumps(list(writers)))
    recover_files(folder)


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike[str], what: str) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (an existing folder) while the block runs, so that two
    processes (``what``: e.g. "fhnn reproduce") never write into it at once; the second is refused
    with a :class:`ConfigError` naming the holder's process id. The lock is ``folder/.lock`` under
    ``flock``: the system releases it when its process ends, even by SIGKILL, so it never goes stale."""
    path = Path(folder) / ".lock"
    handle = open(path, "a+", encoding="utf-8")
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            raise ConfigError(
                f"'{folder}' is in use by another {what} (process {holder}); wait for it to finish or "
                "choose another output folder"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        yield
    finally:
        handle.close()


__all__ = [
    "atomic_output",
    "check_new_folder",
    "check_output_path",
    "check_writable_folder",
    "commit_files",
    "folder_lock",
    "recover_files",
    "write_atomic",
    "write_folder_atomic",
]
