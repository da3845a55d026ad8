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
HEADLINE_ROWS = {
    "FHNN, 1 s": ("T1", "fhnn", 1),
    "Neural ODE, 1 s": ("T1", "node", 1),
    "FHNN, 5 s": ("T2", "fhnn", 5),
    "HNN, 5 s": ("T2", "hnn", 5),
    "LNN, 5 s": ("T2", "lnn", 5),
    "DHN, 5 s": ("T2", "dhn", 5),
    "FHNN, 60 s": ("T3", "fhnn", 60),
}
NUMBER = r"(\d+(?:\.\d+)?(?:e-?\d+)?)"


def _headline_table() -> dict[str, list[str]]:
    text = (ROOT / "README.md").read_text()
    start = text.index("| RMSE(pos) | solid_body_vortex | steady_vortex (actuated) | paper |")
    rows = {}
    for line in text[start:].splitlines()[2:]:
        if not line.startswith("|"):
            break
        label, *cells = [c.strip() for c in line.strip("|").split("|")]
        rows[label] = cells
    return rows


def _records() -> list[dict]:
    """The cells the reproduction wrote (``docs/reproduction/tables.json``)."""
    return json.loads((ROOT / "docs" / "reproduction" / "tables.json").read_text())["cells"]


def _same(printed: str, value: float, digits: int) -> bool:
    """``printed`` is ``value`` rounded to ``digits`` significant digits."""
    return float(f"{value:.{digits - 1}e}") == float(printed)


def test_readme_headline_table_is_the_reproductions_tables_json() -> None:
    """Every cell of the README's headline table is the cell of ``docs/reproduction/tables.json``
    (the file the run wrote) it names: mean and std, a median, or the diverged count."""
    records = _records()
    rows = _headline_table()
    assert set(rows) == set(HEADLINE_ROWS)
    for label, (table, model, horizon) in HEADLINE_ROWS.items():
        for data, cell in zip(("solid_body_vortex", "steady_vortex"), rows[label][:2], strict=True):
            (rec,) = [
                r
                for r in records
                if (r["table"], r["data"], r["model"], r["horizon"], r["metric"])
                == (table, data, model, horizon, "rmse_pos")
            ]
            where = f"README '{label}' on {data}: {cell!r} against {rec}"
            assert float(rows[label][2]) == rec["paper"], where
            if cell.startswith("diverged"):
                assert rec["statistic"] == "median" and rec["mean"] is None, where
                assert f"({rec['diverged']}/{rec['rollouts']} rollouts)" in cell, where
                continue
            if cell.startswith("median"):
                assert rec["statistic"] == "median", where
                assert f"({rec['diverged']}/{rec['rollouts']} diverged)" in cell, where
                assert _same(re.match(r"median " + NUMBER, cell).group(1), rec["mean"], 3), where
                continue
            mean, std = re.match(NUMBER + r" ± " + NUMBER, cell).groups()
            assert rec["statistic"] == "mean" and rec["diverged"] == 0, where
            assert _same(mean, rec["mean"], 3) and _same(std, rec["std"], 2), where


def test_readme_t4_sentence_is_the_reproductions_tables_json() -> None:
    """The README's T4 sentence gives each scenario's FHNN RMSE(pos) at 5 s as the run wrote it,
    and 'N×' as the paper's number over it (or over the paper's, where it says 'worse')."""
    records = _records()
    text = (ROOT / "README.md").read_text()
    start = text.index("T4 (5 s, against the paper's")
    sentence = text[start : text.index("\n\n", start)]
    t4 = [r for r in records if (r["table"], r["model"], r["metric"]) == ("T4", "fhnn", "rmse_pos")]
    assert len(t4) == 5
    for rec in t4:
        match = re.search(
            rf"`{rec['data']}` {NUMBER}(?: ± {NUMBER})? (?:\({NUMBER}×|— \*\*{NUMBER}× worse)", sentence
        )
        assert match, f"README's T4 sentence has no number for {rec['data']}"
        mean, _, better, worse = match.groups()
        assert _same(mean, rec["mean"], 3), (rec["data"], mean, rec["mean"])
        ratio, printed = (
            (rec["paper"] / rec["mean"], better) if better else (rec["mean"] / rec["paper"], worse)
        )
        assert _same(printed, ratio, 2), (rec["data"], printed, ratio)
