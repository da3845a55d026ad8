"""What a killed command may leave and what a reproduction's numbers decide, shared by
``tests/test_faults.py`` and ``benchmarks/reproduction_faults.py``, which stands in for its
killed-reproduction test in the default test run."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

from fhnn.files import JOURNAL

#: The child takes Ctrl-C as a terminal's process does: a suite started as a background job of a
#: non-interactive shell passes SIGINT down ignored, and a Python started so never raises
#: KeyboardInterrupt — the interrupts these checks deliver would be lost.
_MAIN = (
    "import signal; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "from fhnn.cli.app import main; main()"
)


def fhnn_command(*args: str) -> list[str]:
    """The command line of ``fhnn ARGS`` in a new interpreter that takes SIGINT as a terminal's
    process does."""
    return [sys.executable, "-c", _MAIN, *args]


def ended_as(proc: subprocess.CompletedProcess[str], sig: str) -> bool:
    """Whether ``proc``, sent ``SIG<sig>`` (``"KILL"`` or ``"INT"``), ended as that signal ends a
    command: SIGKILL at once (status −9); SIGINT caught, with one ``interrupted`` line last and
    status 130."""
    if sig == "KILL":
        return proc.returncode == -signal.SIGKILL
    return proc.returncode == 130 and "interrupted" in (proc.stderr.splitlines() or [""])[-1]


def leftovers(folder: Path) -> list[str]:
    """Temporary and pending files a killed writer may leave (hidden ``*.tmp`` / ``*.pending``)."""
    return sorted(
        str(p.relative_to(folder))
        for p in folder.rglob(".*")
        if p.name.endswith((".tmp", ".pending")) or p.name == JOURNAL
    )


def reproduction_files(out: Path) -> dict[str, bytes]:
    """Every file a reproduction wrote that its numbers decide (not its timings, run times or the
    date in its provenance stamp)."""
    files = {}
    for path in sorted(out.rglob("*")):
        rel = str(path.relative_to(out))
        if (
            path.is_file()
            and not rel.startswith(("figures", ".lock"))
            and path.suffix not in (".html", ".md")
        ):
            data = path.read_bytes()
            stamped = path.suffix == ".json" and b'"provenance"' in data
            if path.name in ("result.json", "timings.json") or stamped:
                info = json.loads(data)
                if isinstance(info, dict) and isinstance(info.get("provenance"), dict):
                    info["provenance"].pop("date")  # when the file was written, not what it holds
                for key in (
                    "train_seconds",
                    "eval_seconds",
                    "job_seconds_total",
                    "mean_job_seconds",
                    "mean_train_seconds",
                    "mean_eval_seconds",
                ):
                    info.pop(key, None)
                info.pop("wall_seconds_this_run", None)
                data = json.dumps(info, sort_keys=True).encode()
            files[rel] = data
    return files
