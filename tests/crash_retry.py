"""A test whose xdist worker dies of a native fault is run once more, on a fresh worker.

After compiling a program JAX serialises the executable into its persistent compilation cache
(``executable.serialize()`` in ``jax._src.compilation_cache.put_executable_and_time``), and XLA can
abort the process there: a worker of this suite died so three times in recent full runs
(``Fatal Python error: Aborted`` with that frame on top), each time in the same test of
``test_training_programs.py``, which passed in each of 8 runs of it and of its file alone and in
the run that retried it. Deserialised CPU executables are a known source of such crashes
(jax-ml/jax#28908, open). A crash there says nothing of the test, so the test is run again, once;
a test that crashes a second time fails, and a failing assertion is never run again.
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
