"""Does ``fhnn train --max-time`` bound the whole command? Wall clock of ``--max-time 120`` (one
run) and ``--seeds 3 --max-time 600`` (an ensemble) on a table of the own-data trial's size,
against the bound the project holds itself to: the budget plus 10 % plus 15 s. And does the same
command continue what the budget cut? An ensemble of two asked for 200,000 Adam steps under
``--max-time 240``, then the same command under ``--max-time 120``: each member must say that the
budget cut it and where (its history's budget record at that Adam step), and the second command
must continue each member from that step to more Adam steps, within its own bound.

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
    row = {"command": "fhnn " + " ".join(args), "seconds": round(seconds, 1), "ran": ran}
    return {**row, "stdout": done.stdout, "stderr": done.stderr}


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
        rows[name], _, _ = case(name, budget, "train", str(data), "-o", str(folder), *extra)
    record = {**stamp(), "cases": rows}
    if not args.only_single:
        record["continued"] = continued(data, args.out / "run_cut", rows)
    RESULT.parent.mkdir(parents=True, exist_ok=True)
    RESULT.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {RESULT}")


def case(name: str, budget: float, *args: str) -> tuple[dict, str, str]:
    """``fhnn ARGS --max-time BUDGET`` timed against its bound, printed: its row, and what it
    wrote to stdout and stderr (whitespace runs made single spaces)."""
    row = timed(*args, "--max-time", f"{budget:g}")
    out, err = (" ".join(row.pop(stream).split()) for stream in ("stdout", "stderr"))
    row["budget"] = budget
    row["bound"] = budget * 1.1 + 15.0
    row["within"] = row["seconds"] <= row["bound"]
    print(
        f"{name}: {row['seconds']:.1f} s for --max-time {budget:g} (bound {row['bound']:.0f} s): {row['ran']}"
    )
    return row, out, err


#: The cut ensemble: more Adam steps than any budget here allows.
CUT_STEPS = 200_000


def continued(data: Path, folder: Path, rows: dict) -> dict:
    """The cut ensemble and the same command again (adds both to ``rows``): where each member's
    Adam stopped, what each command said, and whether every check held."""
    subprocess.run(["rm", "-rf", str(folder)], check=True)
    command = ["train", str(data), "-o", str(folder), "--seeds", "2", "--steps", str(CUT_STEPS)]
    first, said, _ = case("ensemble_cut", 240.0, *command)
    stopped = [int(a.replace(",", "")) for a in re.findall(rf"Adam ([\d,]+) of {CUT_STEPS:,} steps", said)]
    records = []
    for k in range(len(stopped)):
        history = json.loads((folder / f"seed-{k}" / "run.json").read_text())["history"]
        records.append([r["step"] for r in history if r.get("budget") is True and "phase" not in r])
    again, said_again, told = case("ensemble_continued", 120.0, *command)
    rows["ensemble_cut"], rows["ensemble_continued"] = first, again
    later = [
        int(a.replace(",", "")) for a in re.findall(rf"Adam ([\d,]+) of {CUT_STEPS:,} steps", said_again)
    ]
    checks = {
        "each member's Adam was cut": len(stopped) == 2 and all(0 < s < CUT_STEPS for s in stopped),
        "each said the budget cut it": said.count(
            "(cut by the time budget: run the same command again to continue)"
        )
        == 2,
        "each member's history records the cut at that step": records == [[s] for s in stopped],
        "the same command continued each from that step": all(
            f"seed-{k}: continues the Adam from step {s:,} of {CUT_STEPS:,}" in told
            for k, s in enumerate(stopped)
        ),
        "each ran more Adam steps": len(later) == len(stopped)
        and all(b > a for a, b in zip(stopped, later, strict=False)),
        "both commands within their bounds": first["within"] and again["within"],
    }
    for check, held in checks.items():
        print(f"{'held' if held else 'FAILED'}: {check}")
    return {"adam_stopped": stopped, "adam_after": later, "checks": checks, "held": all(checks.values())}


if __name__ == "__main__":
    main()
