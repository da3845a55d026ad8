"""Regenerate the results the documentation shows.

    python benchmarks/regenerate.py          # the README's results block from the result files
    python benchmarks/regenerate.py --run    # first every benchmark (hours on 2 cores), then that
    python benchmarks/regenerate.py --run --only reproduction,fhnn_targets   # some of them
    python benchmarks/regenerate.py --stale  # which results the current code made stale, and why
    python benchmarks/regenerate.py --run --stale                           # remake just those
    python benchmarks/regenerate.py --if-changed training/tracks.py         # what a change costs

``--run`` runs, one after another, each script that answers a question and writes
``benchmarks/results/NAME.json`` (:data:`QUESTIONS`), then the full reproduction into
``docs/reproduction`` (hours alone on 2 cores; run nothing else meanwhile, the files record
times; ``differentiators.py`` needs the ``compare`` extra, ``pip install -e '.[compare]'``).
The site's tables are made from the files when it is built (``docs/hooks.py``,
``benchmarks/tables.py``); the README's block is written here.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from tables import README_BEGIN, README_END, ROOT, readme_results

#: The questions the Benchmarks page answers, each with the commands (scripts and their
#: arguments) that answer it and the result files (``benchmarks/results/NAME.json``) each writes,
#: in the order they run. Together they write every result file the site shows (checked by
#: ``tests/test_results_current.py``).
QUESTIONS: dict[str, dict[str, list[str]]] = {
    "Is it as accurate as the targets by default?": {"fhnn_targets.py": ["fhnn_targets"]},
    "Does it hold on data nobody tuned on?": {
        "own_data.py --data-seed 3 --skip-speed --result own_data_confirm_seed3": ["own_data_confirm_seed3"],
        "own_data.py --data-seed 4 --skip-speed --result own_data_confirm_seed4": ["own_data_confirm_seed4"],
        "reproduction_confirm.py": ["reproduction_seed3"],
    },
    "How do the other models compare?": {
        "baselines.py": ["baselines"],
        "baselines.py --search": ["baselines_searched"],
    },
    "Would a maintained library do better?": {
        "differentiators.py": ["differentiators"],
        "track_fit_solvers.py": ["track_fit_solvers"],
        "track_fit_solvers.py --tracks 48 --widths 32 --duration 20 --solvers trackfit,qr --steps 10 "
        "--result track_fit_solvers_own_data_size": ["track_fit_solvers_own_data_size"],
    },
    "Are the intervals honest?": {
        "laplace_exact.py": ["laplace_exact"],
        "calibration.py --role confirming --method laplace": ["calibration_laplace_confirming"],
        "calibration.py --role confirming --method laplace --no-forcing": [
            "calibration_laplace_confirming_noforce"
        ],
    },
    "Does it learn a body that turns?": {
        "turning.py --data-seed 3": ["turning_seed3"],
        "turning.py --data-seed 4": ["turning_seed4"],
        "turning_intervals.py --data-seed 20": ["turning_intervals_seed20"],
        "turning_intervals.py --data-seed 21": ["turning_intervals_seed21"],
        "turning_intervals.py --data-seed 22 --obs-noise 0": ["turning_intervals_seed22_noise0"],
        "turning_intervals.py --data-seed 23 --table": ["turning_intervals_seed23_table"],
        "turning_intervals.py --data-seed 23 --table --track-fit": ["turning_intervals_seed23_table_tracks"],
        "turning_intervals.py --data-seed 24 --table": ["turning_intervals_seed24_table"],
        "station_keeping.py --data-seed 3": ["station_keeping_seed3"],
        "shipmmg_check.py --data-seed 3": ["shipmmg_seed3"],
        "shipmmg_check.py --data-seed 5": ["shipmmg_seed5"],
        "shipmmg_check.py --data-seed 9": ["shipmmg_seed9"],
        "shipmmg_check.py --data-seed 11": ["shipmmg_seed11"],
        "shipmmg_check.py --data-seed 3 --controls --no-track-fit": ["shipmmg_controls_seed3"],
        "shipmmg_check.py --data-seed 5 --controls --no-track-fit": ["shipmmg_controls_seed5"],
        "shipmmg_check.py --data-seed 7 --controls --no-track-fit --width 64": ["shipmmg_controls_seed7"],
    },
    "How fast?": {
        "quick_reproduction.py": ["quick_reproduction"],
        "quick_reproduction.py --ray": ["quick_reproduction_ray"],
        "own_data.py --speed-only": ["import_speed"],
        "time_budget.py": ["time_budget"],
    },
    "Does a killed command resume?": {"reproduction_faults.py": ["reproduction_faults"]},
}


def result_scripts() -> dict[str, Path]:
    """Result name (``benchmarks/results/NAME.json``) → the script whose command writes it."""
    here = Path(__file__).resolve().parent
    return {
        name: here / command.split()[0]
        for commands in QUESTIONS.values()
        for command, names in commands.items()
        for name in names
    }


#: The reproduction's stamped files in ``docs/reproduction`` (``--only reproduction`` remakes them).
REPRODUCTION_FILES = ("reproduce.json", "tables.json", "timings.json")


def shown_files() -> list[Path]:
    """Every stamped result file the site shows: the benchmarks' and the reproduction's."""
    results = sorted((ROOT / "benchmarks" / "results").glob("*.json"))
    return results + [ROOT / "docs" / "reproduction" / name for name in REPRODUCTION_FILES]


def script_of(path: Path) -> Path | None:
    """The script that writes the shown result file ``path``; ``None`` for the reproduction's."""
    return result_scripts().get(path.stem) if path.parent.name == "results" else None


def result_name(path: Path) -> str:
    """The name a shown result file goes by: its stem, ``reproduction`` for the reproduction's."""
    return "reproduction" if path.name in REPRODUCTION_FILES else path.stem


def stale_reason_of(path: Path) -> str | None:
    """Why the shown result file ``path`` (:func:`shown_files`) is stale, or ``None``:
    :func:`fhnn.stamps.stale_reason` of its stamp, a benchmark's judged by the files its script
    runs, the reproduction's by every file."""
    from fhnn.stamps import stale_reason

    return stale_reason(json.loads(path.read_text())["provenance"], script_of(path))


def stale_results() -> dict[str, str]:
    """Each shown result the current code has made stale (``reproduction`` for the reproduction's
    files), with why (:func:`stale_reason_of`)."""
    found = {}
    for path in shown_files():
        reason = stale_reason_of(path)
        if reason:
            found[result_name(path)] = reason
    return found


#: Why a result whose script is not bounded by its imports is stale (:func:`stale_if_changed`).
EVERY_FILE = "it is judged by every file it was made with, among them"


def stale_if_changed(files: list[str]) -> dict[str, str]:
    """Each shown result a change to the code of ``files`` (paths relative to the package, e.g.
    ``training/tracks.py``) would make stale, judged as :func:`stale_reason_of` judges it, with
    why; for a change that adds no import (one that does can reach more).

    Raises:
        ValueError: a path of ``files`` is not a file of the package.
    """
    from fhnn.runtime import PACKAGE_ROOT
    from fhnn.stamps import judged_files

    missing = [f for f in files if not (PACKAGE_ROOT / f).is_file()]
    if missing:
        raise ValueError(f"no such file in the package: {', '.join(missing)}")
    found = {}
    for path in shown_files():
        judged, bounded = judged_files(json.loads(path.read_text())["provenance"], script_of(path))
        hit = [f for f in files if f in judged]
        if hit:
            found[result_name(path)] = f"{'its script runs' if bounded else EVERY_FILE} {', '.join(hit)}"
    return found


def recorded_seconds(name: str) -> float | None:
    """The wall time result ``name`` records of the run that made it (``wall_seconds``, else from
    its stamp's ``started`` to its ``date``), if any."""
    import datetime

    path = ROOT / "benchmarks" / "results" / f"{name}.json"
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    seconds = record.get("wall_seconds")
    if isinstance(seconds, (int, float)):
        return float(seconds)
    stamp = record.get("provenance", {})
    if "started" not in stamp:
        return None
    began, ended = (datetime.datetime.fromisoformat(stamp[k]) for k in ("started", "date"))
    return (ended - began).total_seconds()


def write_readme(root: Path = ROOT) -> bool:
    """Rewrite the README's results block; returns whether it changed."""
    readme = root / "README.md"
    text = readme.read_text()
    start, end = text.index(README_BEGIN), text.index(README_END) + len(README_END)
    cells = json.loads((root / "docs" / "reproduction" / "tables.json").read_text())["cells"]
    new = text[:start] + readme_results(cells) + text[end:]
    readme.write_text(new)
    return new != text


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", action="store_true", help="run every benchmark and the full reproduction first")
    p.add_argument(
        "--only",
        default=None,
        help="with --run: only the commands writing these results (comma-separated names of "
        "benchmarks/results files, or 'reproduction'), in the order given; a regeneration spread "
        "over several sittings",
    )
    p.add_argument(
        "--stale",
        action="store_true",
        help="only the results the current code has made stale (as tests/test_results_current.py "
        "judges them); without --run, list them, each with why and its command",
    )
    p.add_argument(
        "--if-changed",
        default=None,
        metavar="FILES",
        help="list the results a change to these package files (comma-separated, relative to "
        "src/fhnn, e.g. training/tracks.py) would make stale, with the wall time each recorded; "
        "changes nothing",
    )
    args = p.parse_args()
    if args.if_changed is not None:
        if args.run or args.stale or args.only is not None:
            p.error("--if-changed only lists: give it alone")
        try:
            stale = stale_if_changed([f.strip() for f in args.if_changed.split(",") if f.strip()])
        except ValueError as e:
            p.error(f"--if-changed: {e}")
        recorded = {name: recorded_seconds(name) for name in stale}
        for name, reason in stale.items():
            seconds = recorded[name]
            print(f"{name}: {reason}" + ("" if seconds is None else f" (made in {seconds / 60:.0f} min)"))
        known = [s for s in recorded.values() if s is not None]
        print(
            f"{len(stale)} of {len(shown_files()) - len(REPRODUCTION_FILES) + 1} shown results would be stale"
            + (f"; {len(known)} of them record {sum(known) / 3600:.1f} h of wall time" if known else "")
        )
        return
    if args.stale and args.only is not None:
        p.error("--stale chooses the results itself: give it or --only, not both")
    here = Path(__file__).resolve().parent
    commands = {c: names for question in QUESTIONS.values() for c, names in question.items()}
    wanted = None if args.only is None else args.only.split(",")
    if args.stale:
        stale = stale_results()
        wanted = list(stale)
        for name, reason in stale.items():
            command = next((c for c, names in commands.items() if name in names), None)
            again = (
                f"benchmarks/{command}" if command else "benchmarks/regenerate.py --run --only reproduction"
            )
            print(f"{name}: {reason}\n    python {again}")
        if not stale:
            print("no shown result is stale")
        if not args.run:
            return
    known = {n for names in commands.values() for n in names} | {"reproduction"}
    if wanted is not None and not set(wanted) <= known:
        unknown = ", ".join(sorted(set(wanted) - known))
        p.error(f"--only: unknown result(s) {unknown}; known: {', '.join(sorted(known))}")
    order = (
        [*commands, "reproduction"]
        if wanted is None
        else [next((c for c, names in commands.items() if name in names), "reproduction") for name in wanted]
    )
    for command in order if args.run else ():
        print(command, flush=True)
        if command == "reproduction":
            reproduce()
        else:
            script, *arguments = command.split()
            subprocess.run([sys.executable, str(here / script), *arguments], check=True)
    print("README.md results block " + ("rewritten" if write_readme() else "unchanged"))


def reproduce() -> None:
    """The full reproduction, its files copied into ``docs/reproduction``."""
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["fhnn", "reproduce", "-o", tmp, "-q"], check=True)
        for name in ("reproduce.json", "timings.json"):
            shutil.copy(Path(tmp) / name, ROOT / "docs" / "reproduction" / name)
        for name in ("tables.json", "tables.md"):
            shutil.copy(Path(tmp) / "tables" / name, ROOT / "docs" / "reproduction" / name)
        for png in (Path(tmp) / "figures").glob("*.png"):
            shutil.copy(png, ROOT / "docs" / "reproduction" / png.name)


if __name__ == "__main__":
    main()
