"""Does a reproduction killed in each of its phases resume to the numbers of one never killed?

``fhnn reproduce --quick`` (every table and figure, one seed) runs once on two workers; while it
runs, a second command on its folder must be refused with one line and change nothing. Then the
same reproduction into another folder on one worker is killed three times, each run resuming the
last: after its first model job (SIGKILL), after the first job of the next run (SIGINT, which must
end with one ``interrupted`` line and status 130), and in the report (SIGKILL). A last run must
run no data set and no job, rebuild the report, leave no temporary file, and write every file the
numbers decide (``tests/fault_checks.py``: timings and dates aside) byte for byte as the
uninterrupted run did. The kills are placed with the command line's ``FHNN_FAULT_AT`` hook, so
each lands in the phase it names. These are the checks of ``tests/test_faults.py``'s
killed-reproduction test, on the quick reproduction instead of a two-job one.

Usage::

    python benchmarks/reproduction_faults.py

Writes ``benchmarks/results/reproduction_faults.json`` (what it printed) when every check held.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import printed_result

from fhnn.api.report import FAULT_ENV

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.fault_checks import ended_as, fhnn_command, leftovers, reproduction_files  # noqa: E402

FAULTS = ("jobs:1:KILL", "jobs:1:INT", "report:0:KILL")


def command(out: Path, workers: int) -> list[str]:
    return fhnn_command("reproduce", "--quick", "-q", "-o", str(out), "--workers", str(workers))


def environment(cache: Path, fault: str | None = None) -> dict[str, str]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "FHNN_JAX_CACHE": str(cache)}
    env.pop(FAULT_ENV, None)
    if fault:
        env[FAULT_ENV] = fault
    return env


def main() -> None:
    checks: dict[str, bool] = {}
    with printed_result("reproduction_faults"), tempfile.TemporaryDirectory(prefix="fhnn-faults-") as tmp:
        base = Path(tmp)
        cache, straight, killed = base / "jax-cache", base / "straight", base / "killed"
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            command(straight, 2), env=environment(cache), stderr=subprocess.PIPE, text=True
        )
        deadline = time.monotonic() + 600
        while (
            time.monotonic() < deadline and not (straight / "reproduce.json").exists() and proc.poll() is None
        ):
            time.sleep(0.05)
        second = subprocess.run(command(straight, 1), env=environment(cache), capture_output=True, text=True)
        held = f"error: '{straight}' is in use by another fhnn reproduce (process {proc.pid})"
        checks["a second command on the running folder is refused in one line"] = (
            second.returncode == 2 and held in second.stderr
        )
        _, stderr = proc.communicate(timeout=3600)
        checks["the uninterrupted run (two workers) succeeds"] = proc.returncode == 0
        print(f"uninterrupted, two workers: {time.perf_counter() - t0:.1f} s")
        for fault in FAULTS:
            t0 = time.perf_counter()
            done = subprocess.run(
                command(killed, 1), env=environment(cache, fault), capture_output=True, text=True
            )
            checks[f"killed at {fault}: ended as that signal ends it"] = ended_as(
                done, fault.rsplit(":", 1)[1]
            )
            print(f"killed at {fault}: status {done.returncode} after {time.perf_counter() - t0:.1f} s")
        t0 = time.perf_counter()
        final = subprocess.run(command(killed, 1), env=environment(cache), capture_output=True, text=True)
        print(f"resumed to the end: {time.perf_counter() - t0:.1f} s; it said: {final.stdout.strip()}")
        ran = re.search(
            r"(\d+) of (\d+) data sets and (\d+) of (\d+) training jobs run, report rebuilt", final.stdout
        )
        checks["the last run runs no data set and no job and rebuilds the report"] = (
            final.returncode == 0 and ran is not None and ran.group(1) == ran.group(3) == "0"
        )
        checks["no temporary or pending file is left"] = leftovers(killed) == []
        a, b = reproduction_files(straight), reproduction_files(killed)
        same = sorted(a) == sorted(b) and all(a[name] == b[name] for name in a)
        checks[f"its {len(b)} files the numbers decide equal the uninterrupted run's, byte for byte"] = same
        if not same:
            differ = sorted(set(a) ^ set(b)) + [n for n in sorted(set(a) & set(b)) if a[n] != b[n]]
            print(f"differ: {', '.join(differ[:10])}")
        for check, ok in checks.items():
            print(f"{'held' if ok else 'FAILED'}: {check}")
        if not all(checks.values()):
            sys.stderr.write(stderr[-2000:] + final.stderr[-2000:])
            raise SystemExit("reproduction_faults: a check failed (no result file written)")


if __name__ == "__main__":
    main()
