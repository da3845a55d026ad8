"""Every result file the documentation shows was made by the current results-affecting code.

A change to the code of a file a result was made with (documentation aside) changes its
:func:`fhnn.runtime.source_digest`; a result file stamped with another digest is stale
(:func:`fhnn.stamps.stale_reason`), and this test names it and the command that regenerates it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fhnn.runtime import PACKAGE_ROOT
from fhnn.stamps import result_files, stale_reason

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
    reason = stale_reason(stamp)
    assert reason is None, (
        f"{name} was made by other results-affecting code than the current (commit {stamp['commit']}): "
        f"{reason}; regenerate it (docs/benchmarks.md names its script)"
    )


def test_a_result_made_with_a_changed_or_removed_file_is_stale(tmp_path, monkeypatch) -> None:
    """Judged on a copy of the package: changing a file's code or removing it makes a stamp
    stale, a change to its documentation or a file added beside it does not."""
    import shutil

    import fhnn.runtime
    import fhnn.stamps

    root = tmp_path / "fhnn"
    shutil.copytree(PACKAGE_ROOT, root, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(fhnn.stamps, "PACKAGE_ROOT", root)
    files = fhnn.stamps.result_files()
    digest = fhnn.runtime.source_digest.__wrapped__  # uncached: the copy changes under the test
    stamp = {"source": digest(tuple(files), root), "files": files}
    monkeypatch.setattr(fhnn.stamps, "source_digest", lambda parts: digest(parts, root))
    assert fhnn.stamps.stale_reason(stamp) is None
    (root / "physics" / "added_later.py").write_text("X = 1\n")
    assert fhnn.stamps.stale_reason(stamp) is None
    flows = root / "physics" / "flows.py"
    text = flows.read_text()
    flows.write_text(text + "\n# a comment\n")
    assert fhnn.stamps.stale_reason(stamp) is None
    flows.write_text(text + "\nEXTRA = 2\n")
    assert "code of its" in fhnn.stamps.stale_reason(stamp)
    flows.write_text(text)
    (root / "physics" / "body.py").unlink()
    assert "physics/body.py" in fhnn.stamps.stale_reason(stamp)
    assert "is not the current" in fhnn.stamps.stale_reason({"source": "0" * 16})


def test_the_package_finds_no_module_by_scanning() -> None:
    """What makes an added file harmless to older results: nothing under the package imports
    modules it discovers on disk, so a new file runs only when a changed file imports it."""
    for path in PACKAGE_ROOT.rglob("*.py"):
        text, name = path.read_text(), path.relative_to(PACKAGE_ROOT).as_posix()
        for needle in ("pkgutil", "iter_modules", "spec_from_file_location", "runpy", "__import__"):
            assert needle not in text, f"{name} uses {needle}"
        # the package's lazy names: imported by a table written in that file itself
        assert "import_module(" not in text or name == "__init__.py", f"{name} imports by name"
    assert "fhnn/stamps.py" not in result_files() and "stamps.py" not in result_files()


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
