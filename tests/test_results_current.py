"""Every result file the documentation shows was made by the current results-affecting code.

A change to the code of a file a result was made with (documentation aside) changes its
:func:`fhnn.runtime.source_digest`; a result file stamped with another digest is stale
(:func:`fhnn.stamps.stale_reason`), and this test names it and the command that regenerates it."""

from __future__ import annotations

import functools
import json
import subprocess
import sys
from pathlib import Path

import pytest

from fhnn.runtime import PACKAGE_ROOT
from fhnn.stamps import file_digests, import_closure, result_files, stale_reason

ROOT = Path(__file__).resolve().parents[1]
PROVENANCE = {"version", "commit", "dirty", "source", "python", "packages", "machine", "date"}


@functools.cache
def _regenerate():
    """``benchmarks/regenerate.py`` as a module."""
    import importlib.util

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        spec = importlib.util.spec_from_file_location("regenerate", ROOT / "benchmarks" / "regenerate.py")
        regenerate = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(regenerate)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return regenerate


#: The result files the site shows: the benchmarks' and the reproduction's.
SHOWN = _regenerate().shown_files()


@pytest.mark.parametrize("path", SHOWN, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_a_shown_result_is_stamped_with_the_current_code(path: Path) -> None:
    record = json.loads(path.read_text())
    stamp = record.get("provenance") if isinstance(record, dict) else None
    name = path.relative_to(ROOT).as_posix()
    assert isinstance(stamp, dict), f"{name} has no provenance"
    assert PROVENANCE <= set(stamp), f"{name}'s provenance lacks {sorted(PROVENANCE - set(stamp))}"
    # a benchmark's result is judged by the files its script runs (the reproduction's by all)
    reason = _regenerate().stale_reason_of(path)
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
    stamp = {"source": fhnn.runtime.source_digest.__wrapped__(tuple(files), root), "files": files}
    assert fhnn.stamps.source_now(files) == stamp["source"]  # the runtime's digest, read now
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


def _copy(tmp_path, monkeypatch) -> Path:
    """A copy of the package that :mod:`fhnn.stamps` judges against."""
    import shutil

    import fhnn.stamps

    root = tmp_path / "fhnn"
    shutil.copytree(PACKAGE_ROOT, root, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(fhnn.stamps, "PACKAGE_ROOT", root)
    return root


def _script(folder: Path, text: str, name: str = "script.py") -> Path:
    folder.mkdir(exist_ok=True)
    (folder / name).write_text(text)
    return folder / name


def test_a_result_is_judged_by_the_files_its_script_runs(tmp_path, monkeypatch) -> None:
    """With each file's digest in its stamp, a result stays current while the files its script
    reaches keep their code, whatever changes elsewhere; a change to one of them makes it stale,
    and a script that starts Python processes of its own is judged by every file."""
    import fhnn.stamps

    root = _copy(tmp_path, monkeypatch)
    files = fhnn.stamps.result_files()
    stamp = {
        "source": fhnn.stamps.source_now(files),
        "files": files,
        "file_digests": file_digests(files),
    }
    bench = tmp_path / "bench"
    _script(bench, "from fhnn.physics import flows\n", "helper.py")
    script = _script(bench, "import helper\n\nhelper.flows\n")
    closure = import_closure(script)
    assert {"physics/__init__.py", "physics/flows.py"} <= set(closure)
    assert "models/fhnn.py" not in closure and "api/train.py" not in closure
    assert stale_reason(stamp, script) is None
    model = root / "models" / "fhnn.py"
    model.write_text(model.read_text() + "\nEXTRA = 2\n")
    assert stale_reason(stamp, script) is None  # not a file the script runs
    assert "code of its" in stale_reason(stamp)  # judged by every file
    flows = root / "physics" / "flows.py"
    text = flows.read_text()
    flows.write_text(text + "\nEXTRA = 2\n")
    assert "files its script runs changed (physics/flows.py)" in stale_reason(stamp, script)
    flows.write_text(text)
    # a file added later: harmless until a file the script runs imports it
    (root / "physics" / "added_later.py").write_text("X = 1\n")
    _script(bench, "from fhnn.physics import flows, added_later\n", "helper.py")
    assert "physics/added_later.py" in import_closure(script) and stale_reason(stamp, script) is None
    flows.write_text(text + "\nfrom fhnn.physics import added_later\n")
    assert "(physics/flows.py)" in stale_reason(stamp, script)
    flows.write_text(text)
    _script(bench, "from fhnn.physics import flows\n", "helper.py")
    assert stale_reason(stamp, script) is None
    # a module it runs, removed (the package binds no such name): said in one line, not raised
    (root / "physics" / "flows.py").rename(root / "physics" / "moved.py")
    assert "imports fhnn.physics.flows, which is not a module" in stale_reason(stamp, script)
    (root / "physics" / "moved.py").rename(root / "physics" / "flows.py")
    # processes of its own (the models file changed above): judged by every file
    for text in (
        "import subprocess, sys\nsubprocess.run([sys.executable, '-c', 'import fhnn'])\n",
        "import subprocess\nsubprocess.run(['fhnn', 'train', 'd.h5'])\n",
        "import importlib\nimportlib.import_module('fhnn.models.fhnn')\n",
    ):
        _script(bench, text, "helper.py")
        assert import_closure(script) is None, text
        assert "code of its" in stale_reason(stamp, script)


def test_the_closure_follows_lazy_names_relative_imports_and_the_package_passed_on(
    tmp_path, monkeypatch
) -> None:
    root = _copy(tmp_path, monkeypatch)
    bench = tmp_path / "bench"
    lazy = set(import_closure(_script(bench, "import fhnn\n\nfhnn.forecast_turning\n")))
    assert "api/planar_forecast.py" in lazy and "api/train.py" not in lazy
    assert "api/planar_forecast.py" in import_closure(_script(bench, "from fhnn import forecast_turning\n"))
    every = set(import_closure(_script(bench, "import fhnn\n\ngetattr(fhnn, 'x')\n")))
    assert {"api/planar_forecast.py", "api/train.py", "api/reproduce.py"} <= every
    (root / "physics" / "relative.py").write_text("from . import body\nfrom .flows import *\n")
    closure = import_closure(_script(bench, "import fhnn.physics.relative\n"))
    assert {"physics/relative.py", "physics/body.py", "physics/flows.py"} <= set(closure)
    for text in ("import fhnn.physics.nowhere\n", "from fhnn.physics import flows, nowhere\n"):
        with pytest.raises(ValueError, match="imports fhnn.physics.nowhere, which is not a module"):
            import_closure(_script(bench, text))


def test_the_closure_holds_every_package_module_a_script_loads() -> None:
    """Imported one after another in a fresh interpreter, each script loads no results-affecting
    module its closure lacks (what loads at import; its functions' imports are written the same
    way)."""
    names = ["shipmmg_check", "laplace_exact", "turning_intervals"]  # tests package; the largest
    code = (
        "import json, sys; sys.path[:0] = ['benchmarks', '.']; sys.argv = ['x']\n"
        "import importlib\nfrom fhnn.runtime import PACKAGE_ROOT\nseen = {}\n"
        "for name in sys.argv[1:] or NAMES:\n"
        "    before = set(sys.modules)\n    importlib.import_module(name)\n"
        "    files = [getattr(sys.modules[m], '__file__', None) for m in set(sys.modules) - before]\n"
        "    seen[name] = [str(__import__('pathlib').Path(f).resolve().relative_to(PACKAGE_ROOT.resolve()))\n"
        "                  for f in files if f and f.startswith(str(PACKAGE_ROOT))]\n"
        "print(json.dumps(seen))\n"
    ).replace("NAMES", repr(names))
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    loaded = json.loads(done.stdout.splitlines()[-1])
    for name in names:
        closure = set(import_closure(ROOT / "benchmarks" / f"{name}.py"))
        assert set(loaded[name]) & set(result_files()) <= closure, name
        assert loaded[name], name  # each loads modules the ones before it did not


def test_the_package_finds_no_module_by_scanning() -> None:
    """What makes an added file harmless to older results: nothing under the package imports
    modules it discovers on disk, so a new file runs only when a changed file imports it."""
    for path in PACKAGE_ROOT.rglob("*.py"):
        text, name = path.read_text(), path.relative_to(PACKAGE_ROOT).as_posix()
        if name == "stamps.py":  # the judge, which names these to look for them; unstamped
            continue
        for needle in ("pkgutil", "iter_modules", "spec_from_file_location", "runpy", "__import__"):
            assert needle not in text, f"{name} uses {needle}"
        # the package's lazy names: imported by a table written in that file itself
        assert "import_module(" not in text or name == "__init__.py", f"{name} imports by name"
    assert "fhnn/stamps.py" not in result_files() and "stamps.py" not in result_files()


def test_the_regeneration_writes_every_shown_result_file() -> None:
    """``benchmarks/regenerate.py --run`` reruns a command for each result file the site shows,
    and no command writes a file the site does not show."""
    regenerate = _regenerate()
    written = [
        name for commands in regenerate.QUESTIONS.values() for names in commands.values() for name in names
    ]
    assert len(written) == len(set(written))
    assert set(written) == {p.stem for p in (ROOT / "benchmarks" / "results").glob("*.json")}
    for commands in regenerate.QUESTIONS.values():
        for command in commands:
            assert (ROOT / "benchmarks" / command.split()[0]).is_file(), command


def test_regenerate_names_just_the_results_a_change_stales(tmp_path, monkeypatch) -> None:
    """``benchmarks/regenerate.py --stale``'s list: with the turning model's training changed on a
    copy of the package, the turning results and none of the point body's, just those
    ``--if-changed`` named before the change."""
    import fhnn.stamps

    regenerate = _regenerate()
    assert regenerate.stale_results() == {}
    predicted = regenerate.stale_if_changed(["training/planar.py"])  # --if-changed, before the change
    with pytest.raises(ValueError, match="no such file in the package: training/gone.py"):
        regenerate.stale_if_changed(["training/gone.py"])
    root = _copy(tmp_path, monkeypatch)
    planar = root / "training" / "planar.py"
    planar.write_text(planar.read_text() + "\nEXTRA = 2\n")
    stale = regenerate.stale_results()
    assert set(stale) == set(predicted)
    assert {"turning_seed3", "shipmmg_seed11", "station_keeping_seed3"} <= set(stale)
    assert not {"fhnn_targets", "laplace_exact", "reproduction"} & set(stale)
    for name, reason in stale.items():
        closure = fhnn.stamps.import_closure(regenerate.result_scripts()[name])
        assert closure is None or "training/planar.py" in closure, name
        assert "training/planar.py" in reason or "code of its" in reason, reason
