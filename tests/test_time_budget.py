"""``fhnn train --max-time``: a bound on the whole command (compilation and every member of an
ensemble included), said in words that tell what ran, and continued by the same command."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fhnn.data.dataset import write_dataset

from .conftest import small_dataset

#: What the issue holds the bound to: within 10 % of the budget plus 15 s.
SLACK_SHARE, SLACK_SECONDS = 0.10, 15.0


def fhnn_process(*args: str) -> tuple[subprocess.CompletedProcess, float]:
    """``fhnn ARGS`` in a new process (Python's start, JAX's import and compilation included):
    the completed process and its wall-clock seconds."""
    t0 = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "fhnn.cli.app", *args], capture_output=True, text=True, timeout=600
    )
    return done, time.monotonic() - t0


@pytest.mark.slow
def test_max_time_bounds_an_ensemble_and_the_same_command_continues_it(tmp_path: Path) -> None:
    """An ensemble of two whose training would take many minutes ends within the bound; each
    member says which phases ran how far and that the budget cut them; the same command again
    continues each member from the Adam step where it stopped (more Adam steps, the polish
    again), within a new budget. Left out of the default run (64 s of a worker in a 2-core suite
    over its 900 s budget): ``benchmarks/time_budget.py`` makes the same checks on a table of the
    own-data trial's size (``benchmarks/results/time_budget.json``)."""
    data = tmp_path / "d.h5"
    write_dataset(small_dataset("steady_vortex", n_traj=12, duration=3.0), data)
    budget = 40.0  # well above what compiling the programs takes on a busy 2-core machine
    command = ["train", str(data), "-o", str(tmp_path / "ens"), "--seeds", "2", "--steps", "200000"]
    command += ["--set", "model.width=16", "--max-time", f"{budget:g}"]
    done, seconds = fhnn_process(*command)
    assert done.returncode == 0, done.stderr[-2000:]
    assert seconds <= budget * (1 + SLACK_SHARE) + SLACK_SECONDS, seconds
    said = " ".join(done.stdout.split())
    ran = re.findall(r"trained fhnn: Adam ([\d,]+) of 200,000 steps, L-BFGS polish ([\d,]+) of 10,000", said)
    assert len(ran) == 2, said
    assert said.count("(cut by the time budget: run the same command again to continue)") == 2
    first = [int(adam.replace(",", "")) for adam, _ in ran]
    for k, adam in enumerate(first):
        history = json.loads((tmp_path / "ens" / f"seed-{k}" / "run.json").read_text())["history"]
        cut = [r for r in history if r.get("budget") is True and "phase" not in r]
        assert [r["step"] for r in cut] == [adam]  # Adam's own cut, where it stopped

    done, seconds = fhnn_process(*command[:-1], "20")
    assert done.returncode == 0, done.stderr[-2000:]
    assert seconds <= 20 * (1 + SLACK_SHARE) + SLACK_SECONDS, seconds
    said_err = " ".join(done.stderr.split())
    for k, adam in enumerate(first):
        assert f"seed-{k}: continues the Adam from step {adam:,} of 200,000" in said_err, said_err
    later = re.findall(r"trained fhnn: Adam ([\d,]+) of 200,000 steps", " ".join(done.stdout.split()))
    assert [int(a.replace(",", "")) for a in later] > first and all(
        int(a.replace(",", "")) > b for a, b in zip(later, first, strict=True)
    )
