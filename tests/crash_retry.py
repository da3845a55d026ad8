"""A test whose xdist worker dies of a native fault is run once more, on a fresh worker.

After compiling a program JAX serialises the executable into its persistent compilation cache
(``executable.serialize()`` in ``jax._src.compilation_cache.put_executable_and_time``), and XLA
aborts the process there (``Fatal Python error: Aborted`` with that frame on top) in one test of
``test_training_programs.py``, at its first ``adam_step``, in each of the last four full runs of the
suite — never when the test runs alone (8 runs of it and of its file) nor when it is run again on a
fresh worker. It depends on what the worker compiled before, which is not understood (JAX's cache
entries are checksummed zlib streams, so a torn file cannot reach XLA; deserialised CPU executables
are a known crash source, jax-ml/jax#28908). A crash there says nothing of the test, so the test
is run again, once; a test that crashes a second time fails, and a failing assertion is never run
again.

The persistent cache is not the cause: with it switched off for a whole run (2026-12-05) the
workers still died twice, both times of a segmentation fault inside XLA's compilation
(``backend_compile_and_load``), in other tests (a quasi-Newton phase of ``fhnn train``, a
plan's first run), and the run took 1,199 s against 1,055 s with the cache. Every full run of
that day had two such crashes, each in a different test.
A rerun is reported as ``R`` and counted as "rerun" in the summary line.
"""

from __future__ import annotations

import pytest

_RERUN: set[str] = set()


@pytest.hookimpl(optionalhook=True)
def pytest_handlecrashitem(crashitem: str, report: pytest.TestReport, sched: object) -> None:
    if crashitem in _RERUN:
        return
    _RERUN.add(crashitem)
    sched.mark_test_pending(crashitem)  # type: ignore[attr-defined]
    report.outcome = "rerun"  # type: ignore[assignment]


def pytest_report_teststatus(report: pytest.TestReport) -> tuple[str, str, tuple[str, dict]] | None:
    if report.outcome == "rerun":
        return "rerun", "R", ("RERUN", {"yellow": True})
    return None
