"""The README's Python example runs as written (so it cannot rot), through the public names of
``fhnn``; its headline reproduction table and T4 sentence are the numbers the run wrote."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import fhnn

ROOT = Path(__file__).resolve().parents[1]


def _python_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text[text.index("## From Python") :]
    match = re.search(r"```python\n(.*?)```", section, re.S)
    assert match, "the README's 'From Python' section has no Python block"
    return match.group(1)


def test_readme_python_example_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(_python_example(), "README.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    rmse = float(lines[0].split()[0])
    assert 0 < rmse < 0.05 and lines[0].endswith("m at 2 s")
    assert 0 <= float(lines[1]) < 1
    assert eval(lines[2]) == ["r", "sigma", "m_ax", "m_ay", "c_q", "c_l", "drag"]
    assert (tmp_path / "sv_run" / "run.json").is_file()


def test_public_names_resolve() -> None:
    for name in fhnn.__all__:
        assert getattr(fhnn, name) is not None, name
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        fhnn.nope  # noqa: B018


#: The README headline table's row labels: (table, model, horizon in s).
def _tables_module():
    """``benchmarks/tables.py``, which makes the README's results block and the site's tables."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("benchmark_tables", ROOT / "benchmarks" / "tables.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_readme_results_are_generated_from_the_reproductions_tables_json() -> None:
    """The README's results block is exactly what ``benchmarks/regenerate.py`` makes from
    ``docs/reproduction/tables.json``: a number typed by hand, or a file regenerated without
    the README, fails here."""
    tables = _tables_module()
    text = (ROOT / "README.md").read_text()
    start = text.index(tables.README_BEGIN)
    block = text[start : text.index(tables.README_END) + len(tables.README_END)]
    cells = json.loads((ROOT / "docs" / "reproduction" / "tables.json").read_text())["cells"]
    assert block == tables.readme_results(cells), "run python benchmarks/regenerate.py"


def test_readme_headline_rows_name_the_reproductions_cells() -> None:
    """The block's numbers are the cells' (FHNN at 1 s on solid_body_vortex, as printed)."""
    tables = _tables_module()
    cells = json.loads((ROOT / "docs" / "reproduction" / "tables.json").read_text())["cells"]
    (rec,) = [
        r
        for r in cells
        if (r["table"], r["data"], r["model"], r["horizon"], r["metric"])
        == ("T1", "solid_body_vortex", "fhnn", 1, "rmse_pos")
    ]
    row = next(line for line in tables.headline(cells).splitlines() if line.startswith("| FHNN, 1 s"))
    mean = float(re.search(r"\| ([0-9.e-]+) ±", row).group(1))
    assert mean == pytest.approx(rec["mean"], rel=5e-3)
