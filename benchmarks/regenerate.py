"""Regenerate the results the documentation shows.

    python benchmarks/regenerate.py          # the README's results block from the result files
    python benchmarks/regenerate.py --run    # first every benchmark (hours on 2 cores), then that

``--run`` runs, one after another, each script that answers a question and writes
``benchmarks/results/NAME.json`` (:data:`QUESTIONS`), then the full reproduction into
``docs/reproduction``. The site's tables are made from the files when it is built
(``docs/hooks.py``, ``benchmarks/tables.py``); the README's block is written here.
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

#: The questions and the commands whose result files answer them, in the order they run.
QUESTIONS = {
    "Is it as accurate as we say by default?": ["fhnn_targets.py"],
    "Does it hold on data nobody tuned on?": [
        "own_data.py --data-seed 3 --skip-speed --result own_data_confirm_seed3",
        "own_data.py --data-seed 4 --skip-speed --result own_data_confirm_seed4",
        "reproduction_confirm.py",
    ],
    "How fast does it import?": ["own_data.py --speed-only"],
    "How fast does it train?": ["training_speed.py"],
    "Does --max-time hold?": ["time_budget.py"],
    "Does held thrust pay?": ["held_thrust.py --max-time 480"],
    "Does the frame matter?": ["frame_invariance.py"],
    "How do the baselines do?": ["baselines.py"],
    "How fast is the simulator?": ["simulate.py"],
    "How fast is the quick reproduction?": ["quick_reproduction.py"],
}


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
    args = p.parse_args()
    here = Path(__file__).resolve().parent
    if args.run:
        for question, commands in QUESTIONS.items():
            print(question, flush=True)
            for command in commands:
                script, *arguments = command.split()
                subprocess.run([sys.executable, str(here / script), *arguments], check=True)
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(["fhnn", "reproduce", "-o", tmp, "-q"], check=True)
            for name in ("reproduce.json", "timings.json"):
                shutil.copy(Path(tmp) / name, ROOT / "docs" / "reproduction" / name)
            for name in ("tables.json", "tables.md"):
                shutil.copy(Path(tmp) / "tables" / name, ROOT / "docs" / "reproduction" / name)
            for png in (Path(tmp) / "figures").glob("*.png"):
                shutil.copy(png, ROOT / "docs" / "reproduction" / png.name)
    print("README.md results block " + ("rewritten" if write_readme() else "unchanged"))


if __name__ == "__main__":
    main()
