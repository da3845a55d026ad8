"""Does a turning body's noisy table train as well as its simulation? Import, train, compare.

For each of ``turning_vortex`` and ``turning_time_varying_vortex``: simulate ``--data-seed``'s
trajectories (``benchmarks/turning.py``'s, sampled every 0.01 s), give them as a tracker would
(:func:`fhnn.data.planar_table.observed_table`: every 3rd to 7th sample, 0.03-0.07 s apart, with
``--position-noise`` [m] on x, y and ``--heading-noise`` [rad] on the heading, known body-frame
forces), import the table (:func:`fhnn.api.planar.import_turning`), train with the defaults and
compare with the simulator's truth: the added masses, the damping and the flow as
``benchmarks/turning.py`` does, and RMSE of position and heading at 5 s on the test split against
the noise-free truth and against the table's own (noisy) observations. The import's velocity
error against the truth is reported too. Seeds: ``benchmarks/seeds.toml`` ``[turning]``.

    python benchmarks/turning_table.py --data-seed 3
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, seed_role, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.api.planar import evaluate_turning, import_turning, simulate_turning, train_turning
from fhnn.data.planar_table import observed_table
from fhnn.evaluation.planar import checkpoints, forecast

SCENARIOS = ("turning_vortex", "turning_time_varying_vortex")
STEP = 0.01
HORIZON = 5.0


def truth_of(imported, source, split: str) -> np.ndarray:
    """The simulation's noise-free states at the imported split's samples, ``(N, T, 6)``."""
    part = imported.splits[split]
    out = np.array(part.states_clean)
    for k, traj_id in enumerate(imported.params["ids"][split]):
        name, i = traj_id.split("-")
        rows = np.rint(part.t[k, : part.lengths[k]] / STEP).astype(int)
        out[k, : part.lengths[k]] = source.splits[name].states_clean[int(i), rows]
    return out


def run(name: str, seed: int, position_noise: float, heading_noise: float) -> dict:
    start = time.perf_counter()
    data = simulate_turning(name, seed=seed, dt=STEP)
    table = observed_table(
        data, position_noise=position_noise, heading_noise=heading_noise, steps=(3, 7), seed=seed
    )
    imported = import_turning(table_frame(table), mass=data.mass, inertia=data.inertia, seed=seed)
    train = imported.splits["train"]
    own = train.valid()
    state_error = np.sqrt(np.mean((train.states[own] - truth_of(imported, data, "train")[own]) ** 2, axis=0))

    def progress(phase: str, step: int, steps: int, loss: float) -> None:
        if step % 1000 == 0 or step == steps:
            print(f"  {name} {phase} {step}/{steps} train loss {loss:.3e}", flush=True)

    fit = train_turning(imported, progress=progress)
    # the recovery against the truth: the imported data set with the scenario's parameters
    judged = dataclasses.replace(imported, params={**data.params})
    report = evaluate_turning(fit.model, judged, horizon=HORIZON)
    report["forecast_observed"] = report.pop("forecast")
    test = imported.splits["test"]
    pred, ok = forecast(fit.model, test, HORIZON)
    idx = checkpoints(test, HORIZON)
    rows = np.arange(idx.shape[0])[:, None]
    err = pred[rows, idx] - truth_of(imported, data, "test")[rows, idx]
    report["forecast_truth"] = {
        "rmse_pos": float(np.sqrt(np.mean(err[..., :2] ** 2))) if ok.all() else float("inf"),
        "rmse_heading": float(np.sqrt(np.mean(err[..., 2] ** 2))) if ok.all() else float("inf"),
    }
    report["import"] = {
        "noise_estimate": imported.params["noise"],
        "smoother": imported.params["smoother"],
        "rms_state_error": dict(zip(("x", "y", "psi", "u", "v", "r"), map(float, state_error), strict=True)),
        "rows": int(table["t"].size),
    }
    report["train_seconds"] = fit.seconds
    report["val_loss"] = fit.val_loss
    report["wall_seconds"] = time.perf_counter() - start
    return report


def table_frame(columns: dict) -> object:
    import pandas as pd

    return pd.DataFrame(columns)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=3)
    p.add_argument("--position-noise", type=float, default=1e-3)
    p.add_argument("--heading-noise", type=float, default=3.5e-3)
    p.add_argument("--scenarios", default=",".join(SCENARIOS))
    args = p.parse_args()
    runs = {}
    for name in args.scenarios.split(","):
        report = run(name, args.data_seed, args.position_noise, args.heading_noise)
        runs[name] = report
        masses = ", ".join(f"{k} {v['rel_error']:.2%}" for k, v in report["added_mass"].items())
        damping = ", ".join(f"{a} {report['damping'][a]['rel_l2']:.2%}" for a in ("surge", "sway", "yaw"))
        f, o = report["forecast_truth"], report["forecast_observed"]
        print(
            f"{name}: RMSE(pos)@5s {f['rmse_pos']:.3g} m (truth), {o['rmse_pos']:.3g} m (observed); heading "
            f"{f['rmse_heading']:.3g} rad; masses {masses}; damping {damping}; "
            f"flow {report['flow']['rel_l2']:.3%}; trained in {report['train_seconds']:.0f} s",
            flush=True,
        )
    record = {
        **stamp(),
        "data_seed": args.data_seed,
        "seed_role": seed_role("turning", args.data_seed),
        "position_noise": args.position_noise,
        "heading_noise": args.heading_noise,
        "sampling": "every 3rd to 7th sample of 0.01 s (0.03-0.07 s)",
        "runs": runs,
    }
    target = RESULTS / f"turning_table_seed{args.data_seed}.json"
    target.write_text(json.dumps(record, indent=1))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
