"""Does ``fhnn train --max-time`` bound the whole command? Wall clock of ``--max-time 120`` (one
run) and ``--seeds 3 --max-time 600`` (an ensemble) on a table of the own-data trial's size,
against the bound the project holds itself to: the budget plus 10 % plus 15 s.

The table: ``steady_vortex`` with actuation, 40 tracks of 30 s observed about every 0.1 s (±30 %)
with 2 mm position noise, imported by ``fhnn import``. Each command runs in a new process (the
interpreter's start, JAX's import and every compilation count), as a user types it.

Usage::

    python benchmarks/time_budget.py [--out DIR] [--only-single]

Writes ``benchmarks/results/time_budget.json``.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

from _common import stamp

from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.data.table import write_table
from fhnn.physics.scenarios import get_scenario

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "benchmarks" / "results" / "time_budget.json"


def make_table(out: Path) -> Path:
    """The trial-sized table, imported; returns the data set's path."""
    sc = get_scenario("steady_vortex")
    config = SimulationConfig.for_scenario(
        sc, n_traj=40, duration=30.0, test_duration=30.0, dt=0.01, actuation="random", seed=11
    )
    fine = simulate_dataset(sc, config)
    table = observe(fine, step=0.1, jitter=0.3, noise=2e-3, seed=12, forces=True)
    csv = write_table(table, out / "tank.csv")
    data = out / "tank.h5"
    data.unlink(missing_ok=True)
    area = str(fine.body_params["A"])
    run = ["import", str(csv), "-o", str(data), "--mass", "10", "--area", area, "-q"]
    subprocess.run([sys.executable, "-m", "fhnn.cli.app", *run], check=True)
    return data


def timed(*args: str) -> dict:
    """``fhnn ARGS`` in a new process: wall seconds and what it said it ran."""
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "fhnn.cli.app", *args], capture_output=True, text=True)
    seconds = time.monotonic() - t0
    if done.returncode != 0:
        raise SystemExit(f"fhnn {' '.join(args)} failed: {done.stderr[-500:]}")
    ran = re.findall(r"trained fhnn: ([^;]+);", " ".join(done.stdout.split()))
    return {"command": "fhnn " + " ".join(args), "seconds": round(seconds, 1), "ran": ran}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("/tmp/fhnn_time_budget"))
    p.add_argument("--only-single", action="store_true", help="the --max-time 120 command alone")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    data = make_table(args.out)
    cases = [("single", 120.0, [])]
    if not args.only_single:
        cases.append(("ensemble", 600.0, ["--seeds", "3"]))
    rows = {}
    for name, budget, extra in cases:
        folder = args.out / f"run_{name}"
        subprocess.run(["rm", "-rf", str(folder)], check=True)
        row = timed("train", str(data), "-o", str(folder), *extra, "--max-time", f"{budget:g}")
        row["budget"] = budget
        row["bound"] = budget * 1.1 + 15.0
        row["within"] = row["seconds"] <= row["bound"]
        rows[name] = row
        bound = f"bound {row['bound']:.0f} s"
        print(f"{name}: {row['seconds']:.1f} s for --max-time {budget:g} ({bound}): {row['ran']}")
    RESULT.parent.mkdir(parents=True, exist_ok=True)
    RESULT.write_text(json.dumps({**stamp(), "cases": rows}, indent=1) + "\n")
    print(f"wrote {RESULT}")


if __name__ == "__main__":
    main()
