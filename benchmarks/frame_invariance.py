"""Does a model of imported data depend on where the table's origin is or which way its axes
point? The same table (an isotropic body in ``steady_vortex`` with sinusoidal thrust, 24 tracks of
20 s observed about every 0.05 s ± 30 % with 1 mm noise) is imported and trained by the default
pipeline (at most 120 s each) as given, translated by (100, −50) m, and rotated by 30° (about the origin, then
translated); a second training seed on the original measures training noise. Each model's flow
at the training positions, coefficients on a grid of (r, σ) and a 5 s forecast of every test
track from its first second are taken back to the original frame and compared with the
original's: relative L2 differences, to be set beside the seed's.

Usage::

    python benchmarks/frame_invariance.py [--out DIR]

Writes ``benchmarks/results/frame_invariance.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pandas as pd
from _common import stamp

import fhnn
from fhnn.data.observation import observe
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.evaluation.recovery import coefficients_at
from fhnn.physics.scenarios import get_scenario

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "benchmarks" / "results" / "frame_invariance.json"
SHIFT = np.array([100.0, -50.0])
ANGLE = np.pi / 6
TURN = np.array([[np.cos(ANGLE), -np.sin(ANGLE)], [np.sin(ANGLE), np.cos(ANGLE)]])
#: Seconds each training may take (``--max-time``): the comparison, not convergence, is the point.
BUDGET = 120.0
FRAMES = {  # name: (turn, shift, training seed)
    "original": (np.eye(2), np.zeros(2), 0),
    "seed 1": (np.eye(2), np.zeros(2), 1),
    "translated": (np.eye(2), SHIFT, 0),
    "rotated": (TURN, SHIFT, 0),
}


def moved(table: dict[str, np.ndarray], turn: np.ndarray, shift: np.ndarray) -> dict[str, np.ndarray]:
    out = dict(table)
    for a, b in (("x", "y"), ("Fx", "Fy")):
        both = np.stack([table[a], table[b]], axis=-1) @ turn.T + (shift if a == "x" else 0.0)
        out[a], out[b] = both[:, 0], both[:, 1]
    return out


def physics(fit: fhnn.Fit, table: dict, tests: list[str], turn: np.ndarray, shift: np.ndarray) -> dict:
    model = fit.models[0]
    pos = np.stack([table["x"], table["y"]], axis=-1)[::5]
    flow = np.array([model.eom.flow.velocity(jnp.asarray(p @ turn.T + shift), 0.0) for p in pos]) @ turn
    rs = jnp.asarray([[r, s] for r in np.linspace(0.5, 2.5, 5) for s in (0.05, 0.1, 0.2, 0.4)])
    coefficients = np.asarray(coefficients_at(model.eom.coefficients, rs))
    keep = np.isin(table["traj_id"].astype(str), tests) & (table["t"] - table["t"].min() <= 1.0)
    history = {k: v[keep] for k, v in table.items()}
    forecast = fit.predict(5.0, history=pd.DataFrame(moved(history, turn, shift)), samples=0).columns
    xy = (np.stack([forecast["x"], forecast["y"]], axis=-1) - shift) @ turn
    return {"flow": flow, "coefficients": coefficients, "forecast": xy}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("/tmp/fhnn_frame"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    scenario = dataclasses.replace(get_scenario("steady_vortex"), m_ax=16.0, m_ay=16.0)
    config = SimulationConfig.for_scenario(
        scenario, n_traj=24, duration=20.0, test_duration=20.0, dt=0.01, actuation="random", seed=21
    )
    table = observe(simulate_dataset(scenario, config), step=0.05, jitter=0.3, noise=1e-3, seed=22)
    got, seconds = {}, {}
    tests: list[str] = []
    for name, (turn, shift, seed) in FRAMES.items():
        began = time.monotonic()
        data = fhnn.import_table(pd.DataFrame(moved(table, turn, shift)), mass=10.0, area=0.02)
        tests = data.extra["import"]["traj_ids"]["test"]
        fit = fhnn.train(data, args.out / name.replace(" ", "_"), seed=seed, max_time=BUDGET, progress=False)
        got[name] = physics(fit, table, tests, turn, shift)
        seconds[name] = time.monotonic() - began
        print(f"{name}: trained and compared in {seconds[name]:.0f} s", flush=True)
    first = got["original"]
    diffs = {
        name: {k: float(np.linalg.norm(v[k] - first[k]) / np.linalg.norm(first[k])) for k in first}
        for name, v in got.items()
        if name != "original"
    }
    for name, d in diffs.items():
        print(f"{name:>10}: " + ", ".join(f"{k} {v:.2e}" for k, v in d.items()))
    RESULT.parent.mkdir(exist_ok=True)
    record = {**stamp(), "relative_difference_to_original": diffs, "seconds": seconds}
    RESULT.write_text(json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
