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


def test_the_regeneration_writes_every_shown_result_file(monkeypatch) -> None:
    """``benchmarks/regenerate.py --run`` reruns a command for each result file the site shows,
    and no command writes a file the site does not show."""
    import importlib.util

    monkeypatch.syspath_prepend(str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("regenerate", ROOT / "benchmarks" / "regenerate.py")
    regenerate = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(regenerate)
    written = [
        name for commands in regenerate.QUESTIONS.values() for names in commands.values() for name in names
    ]
    assert len(written) == len(set(written))
    assert set(written) == {p.stem for p in (ROOT / "benchmarks" / "results").glob("*.json")}
    for commands in regenerate.QUESTIONS.values():
        for command in commands:
            assert (ROOT / "benchmarks" / command.split()[0]).is_file(), command
