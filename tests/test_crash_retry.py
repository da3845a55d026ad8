"""The suite's retry of tests whose worker crashed (``tests/crash_retry.py``), run on a toy suite."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

TOY = """
import os
from pathlib import Path


def test_dies_once():
    mark = Path(os.environ["CRASH_MARK"])
    if not mark.exists():
        mark.write_text("crashed once")
        os.abort()


def test_dies_twice():
    os.abort()


def test_fails():
    assert 1 == 2
"""


def test_a_crashed_test_runs_once_more_and_a_failed_one_does_not(tmp_path: Path) -> None:
    (tmp_path / "test_toy.py").write_text(TOY)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "CRASH_MARK": str(tmp_path / "mark"), "PYTHONPATH": str(root)}
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-n",
            "1",
            "-p",
            "tests.crash_retry",
            "-p",
            "no:cacheprovider",
            "-c",
            str(tmp_path / "pytest.ini"),
            "--rootdir",
            str(tmp_path),
            str(tmp_path),
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    summary = out.stdout.strip().splitlines()[-1]
    assert out.returncode == 1, out.stdout[-3000:]
    # dies once: run again and passes; dies twice: fails; a failing assertion: not run again
    assert "2 failed, 1 passed, 2 rerun" in summary, summary
    assert (tmp_path / "mark").read_text() == "crashed once"
    assert (
        "FAILED test_toy.py::test_fails" in out.stdout and "FAILED test_toy.py::test_dies_twice" in out.stdout
    )
