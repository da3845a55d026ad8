"""Whether a stamped result was made by the current code.

A result file's provenance (:func:`fhnn.runtime.provenance`) records ``source``, the digest of the
results-affecting code, and, since this module exists, ``files``: the results-affecting files that
digest covered (paths relative to :data:`fhnn.runtime.PACKAGE_ROOT`). A result is current while
those files exist and their code (syntax trees, documentation aside) still has that digest. A file
added after the result was made cannot have moved it: it reaches a result only through an
existing file that imports it, and that file's change makes the result stale (the package finds no
module by scanning; ``tests/test_results_current.py`` checks that). A stamp without ``files`` is
judged against every results-affecting file, as before.
"""

from __future__ import annotations

from collections.abc import Mapping

from fhnn.runtime import PACKAGE_ROOT, RESULT_SOURCES, source_digest


def result_files() -> list[str]:
    """The ``.py`` files under :data:`fhnn.runtime.RESULT_SOURCES`, relative to the package root,
    sorted: what :func:`fhnn.runtime.source_digest` of them covers."""
    files: set[str] = set()
    for part in RESULT_SOURCES:
        path = PACKAGE_ROOT / part
        found = path.rglob("*.py") if path.is_dir() else [path]
        files.update(p.relative_to(PACKAGE_ROOT).as_posix() for p in found)
    return sorted(files)


def stale_reason(stamp: Mapping[str, object]) -> str | None:
    """Why a result stamped with ``stamp`` (a provenance record) was made by other code than the
    current, or ``None`` when it was not.

    Raises:
        ValueError: ``stamp`` lacks ``source``, or its ``files`` is not a list of strings.
    """
    if "source" not in stamp:
        raise ValueError("the provenance has no 'source' digest")
    files = stamp.get("files")
    if files is None:
        current = source_digest(RESULT_SOURCES)
        if stamp["source"] != current:
            return f"its source {stamp['source']} is not the current {current}"
        return None
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        raise ValueError("the provenance's 'files' is not a list of paths")
    missing = [f for f in files if not (PACKAGE_ROOT / f).is_file()]
    if missing:
        return f"{len(missing)} of the files it was made with are gone ({', '.join(missing[:3])})"
    current = source_digest(tuple(files))
    if stamp["source"] != current:
        return f"the code of its {len(files)} files changed (source {stamp['source']}, now {current})"
    return None


__all__ = ["result_files", "stale_reason"]
