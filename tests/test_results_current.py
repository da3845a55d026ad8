"""Every result file the documentation shows was made by the current results-affecting code.

A change to the code under :data:`fhnn.runtime.RESULT_SOURCES` (documentation aside) changes
:func:`fhnn.runtime.source_digest`; a result file stamped with another digest is stale, and this
test names it and the command that regenerates it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fhnn.runtime import RESULT_SOURCES, source_digest

ROOT = Path(__file__).resolve().parents[1]
#: The result files the site shows: the benchmarks' and the reproduction's.
SHOWN = sorted((ROOT / "benchmarks" / "results").glob("*.json")) + [
    ROOT / "docs" / "reproduction" / name for name in ("reproduce.json", "tables.json", "timings.json")
]
PROVENANCE = {"version", "commit", "dirty", "source", "python", "packages", "machine", "date"}


@pytest.mark.parametrize("path", SHOWN, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_a_shown_result_is_stamped_with_the_current_code(path: Path) -> None:
    record = json.loads(path.read_text())
    stamp = record.get("provenance") if isinstance(record, dict) else None
    name = path.relative_to(ROOT).as_posix()
    assert isinstance(stamp, dict), f"{name} has no provenance"
    assert PROVENANCE <= set(stamp), f"{name}'s provenance lacks {sorted(PROVENANCE - set(stamp))}"
    assert stamp["source"] == source_digest(RESULT_SOURCES), (
        f"{name} was made by other results-affecting code (source {stamp['source']}, commit "
        f"{stamp['commit']}) than the current ({source_digest(RESULT_SOURCES)}): regenerate it "
        "(docs/benchmarks.md names its script)"
    )
