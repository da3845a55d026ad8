"""Thrusters that switch between samples: does training on the held forcing (``fhnn import
--forcing thrust.csv --forcing-hold previous``) forecast better than training on forces logged at
the samples (``Fx, Fy`` columns, interpolated), and how much of the gain is the forecast's own
forcing?

The table (issue 73's trial): ``steady_vortex``'s body and flow, 40 tracks of 30 s per split
(train / val / test as simulated: 60 + 15 + 15 tracks into one table, split 70/20/10 on import),
thrust per axis uniform in ±1 N held for 2 s between switches at a random phase per track (so
switches fall between samples), positions observed about every 0.1 s (±30 %) with 2 mm noise.
The truth is integrated stepping onto every switch (:func:`fhnn.data.simulate.integrate_held`).

Both data sets train with the default plan under the same ``--max-time``. Each test track is
forecast from a fit to its first 10 s of observations, 5 s and 15 s ahead, against the
noise-free truth, with the switch times given (``--forcing-hold previous``) and, for the run
trained on logged forces, also with those logged forces interpolated, as a user had to before.

Usage::

    python benchmarks/held_thrust.py [--out DIR] [--max-time SECONDS]

Writes ``benchmarks/results/held_thrust.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
from _common import stamp

import fhnn
from fhnn.api.predict import check_band
from fhnn.data.dataset import SPLITS
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, integrate_held, simulate_dataset
from fhnn.physics.scenarios import get_scenario

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "benchmarks" / "results" / "held_thrust.json"
#: Thrust per axis U(−AMPLITUDE, AMPLITUDE) [N], held HOLD s between switches.
AMPLITUDE, HOLD = 1.0, 2.0
#: Seconds of each test track fitted, and forecast horizons [s].
HISTORY, HORIZONS = 10.0, (5.0, 15.0)


def make_data() -> tuple[pd.DataFrame, pd.DataFrame, dict[str, tuple[np.ndarray, np.ndarray]], dict]:
    """``(observed table with logged Fx, Fy, thrust table, truth per track id (t, states), the
    body's constants)``."""
    sc = get_scenario("steady_vortex")
    config = SimulationConfig.for_scenario(
        sc, n_traj=40, duration=30.0, test_duration=30.0, dt=0.01, actuation="none", seed=11
    )
    base = simulate_dataset(sc, config)
    eom, rng = base.equations(), np.random.default_rng(21)
    splits, thrust, truth, k = {}, [], {}, 0
    for name in SPLITS:
        split = base[name]
        rows = []
        for _ in range(split.n_traj):
            switches = np.arange(rng.uniform(0.0, HOLD), split.t[-1], HOLD)
            times = np.r_[0.0, switches]
            rows.append((times, rng.uniform(-AMPLITUDE, AMPLITUDE, (times.size, 2))))
        states, forces, _, ok = integrate_held(eom, split.states_clean[:, 0], split.t, rows)
        if not ok.all():
            raise SystemExit(f"the truth's solve failed on {int((~ok).sum())} {name} track(s)")
        splits[name] = dataclasses.replace(split, states=states, states_clean=states, forces=forces)
        for i, (times, force) in enumerate(rows):
            thrust.append(pd.DataFrame({"traj_id": str(k), "t": times, "Fx": force[:, 0], "Fy": force[:, 1]}))
            truth[str(k)] = (split.t, states[i])
            k += 1
    held = dataclasses.replace(base, splits=splits)
    table = pd.DataFrame(observe(held, step=0.1, jitter=0.3, noise=2e-3, seed=12, forces=True))
    table["traj_id"] = table["traj_id"].astype(int).astype(str)
    return table, pd.concat(thrust, ignore_index=True), truth, base.body_params


def forecast_errors(
    run: Path, table: pd.DataFrame, thrust: pd.DataFrame, hold: str, truth: dict, ids: list[str]
) -> dict[str, float]:
    """Median (over the test tracks) position error [mm] at each horizon."""
    history = table[table["traj_id"].isin(ids)]
    history = history[history["t"] <= history.groupby("traj_id")["t"].transform("min") + HISTORY]
    history = history.drop(columns=["Fx", "Fy"])
    got = fhnn.predict(
        str(run), max(HORIZONS), history=history, forcing=thrust, forcing_hold=hold, dt=0.05, check=False
    ).columns
    out = {}
    for horizon in HORIZONS:
        errors = []
        for traj in ids:
            rows = np.flatnonzero(np.asarray(got["traj_id"]) == traj)
            t = np.asarray(got["t"])[rows]
            at = rows[int(np.argmin(np.abs(t - (t[0] + horizon))))]
            tt, states = truth[traj]
            want = [np.interp(got["t"][at], tt, states[:, a]) for a in range(2)]
            errors.append(np.hypot(got["x"][at] - want[0], got["y"][at] - want[1]))
        out[f"{horizon:g} s"] = round(1e3 * float(np.median(errors)), 2)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("/tmp/fhnn_held_thrust"))
    p.add_argument("--max-time", type=float, default=600.0, help="each run's training budget [s]")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    table, thrust, truth, body = make_data()
    known = {"mass": body["M"], "area": body["A"]}
    # forces logged at the samples, interpolated (before), and the thrust table held (now)
    logged_forces = table[["traj_id", "t", "Fx", "Fy"]]
    datasets = {
        "logged": fhnn.import_table(table, args.out / "logged.h5", **known),
        "held": fhnn.import_table(
            table.drop(columns=["Fx", "Fy"]),
            args.out / "held.h5",
            **known,
            forcing=thrust,
            forcing_hold="previous",
        ),
    }
    ids = datasets["held"].extra["import"]["traj_ids"]["test"]
    assert ids == datasets["logged"].extra["import"]["traj_ids"]["test"]
    rows = {}
    for name, data in datasets.items():
        folder = args.out / f"run_{name}"
        t0 = time.monotonic()
        fit = fhnn.train(data, folder, max_time=args.max_time, progress=False)
        seconds = time.monotonic() - t0
        band = check_band(fit)
        rows[name] = {
            "train_seconds": round(seconds, 1),
            "ran": fit.run.ran(),
            "forecast_mm_held_switches": forecast_errors(folder, table, thrust, "previous", truth, ids),
            "band_check": None if band is None else band.to_dict(),
        }
        if name == "logged":
            rows[name]["forecast_mm_logged_forces"] = forecast_errors(
                folder, table, logged_forces, "linear", truth, ids
            )
        print(name, json.dumps(rows[name], indent=1))
    RESULT.parent.mkdir(parents=True, exist_ok=True)
    RESULT.write_text(
        json.dumps(
            {
                **stamp(),
                "test_tracks": len(ids),
                "max_time": args.max_time,
                "runs": rows,
            },
            indent=1,
        )
        + "\n"
    )
    print(f"wrote {RESULT}")


if __name__ == "__main__":
    main()
