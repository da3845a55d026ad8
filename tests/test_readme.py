"""The README's Python example runs as written (so it cannot rot), through the public names of
``fhnn``."""

from __future__ import annotations

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
    assert (tmp_path / "sv_run" / "run.json").is_file()


def test_public_names_resolve() -> None:
    for name in fhnn.__all__:
        assert getattr(fhnn, name) is not None, name
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        fhnn.nope  # noqa: B018
