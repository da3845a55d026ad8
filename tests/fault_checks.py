"""What a killed command may leave and what a reproduction's numbers decide, shared by
``tests/test_faults.py`` and ``benchmarks/reproduction_faults.py``, which stands in for its
killed-reproduction test in the default test run."""

from __future__ import annotations

import json
from pathlib import Path

from fhnn.files import JOURNAL


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
