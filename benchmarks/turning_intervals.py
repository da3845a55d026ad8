"""Do a turning body's ensemble intervals hold the truth? ``fhnn turning train --seeds 3`` at its
defaults, then ``fhnn turning inspect``'s intervals against the simulator.

For ``--data-seed N`` (``benchmarks/seeds.toml``, ``[turning_intervals]``: confirming seeds only,
nothing is chosen here): simulate ``turning_vortex`` (the defaults: 100 trajectories of 20 s at
0.05 s) with ``--obs-noise`` on every stored state entry, train ``--members`` members, each on its
own bootstrap of the training tracks (:func:`fhnn.api.planar_ensemble.train_turning_ensemble`),
and report per quantity (added masses, each axis's equivalent linear damping ``X_d/u_r``, ...):
the members' median, its relative error, the 90 % interval's relative width and whether it holds
the truth; for the damping also the fraction of covered relative velocities whose true force the
pointwise interval holds; and each member's RMSE of position and heading at 5 s on the test split.
One data set says little about coverage; the result file says how many there are.

``--table`` takes a user's route instead: the noise-free simulation observed as a tracker would
give it (:func:`fhnn.data.planar_table.observed_table`: every sample, ``--obs-noise`` on ``x, y``
[m] and on the heading [rad], the known forces), imported as ``fhnn import`` imports a table
(:func:`fhnn.api.planar.import_turning`: noise estimated, poses smoothed, velocities estimated),
and the ensemble trained on the import (the same 70/20/10 split of the 100 trajectories, drawn
anew). The intervals are compared with the simulator's truth over the import's covered relative
velocities; the forecasts are scored on the import's test split against its observed poses.

``--track-fit`` then fits each member to the observed poses of its own bootstrap
(:func:`fhnn.training.planar_tracks.fit_planar_tracks` at its defaults: 10 s windows, 300 L-BFGS
iterations, kept only where it lowers the validation windows' misfit) and reports the fitted
members' intervals too, in a second file (``..._tracks``); the first is written before it starts.

    python benchmarks/turning_intervals.py --data-seed 20 [--obs-noise 0.001] [--members 3] [--table]
        [--track-fit]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
from _common import RESULTS, seed_role, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.api.planar import evaluate_turning, import_turning, simulate_turning
from fhnn.api.planar_ensemble import (
    ensemble_coefficients,
    evaluate_turning_ensemble,
    inspect_turning_ensemble,
    train_turning_ensemble,
)
from fhnn.data.planar import PlanarDataset
from fhnn.data.planar_table import observed_table
from fhnn.training.ensemble import read_seeds
from fhnn.training.planar_ensemble import bootstrap_planar
from fhnn.training.planar_tracks import PlanarTrackConfig, fit_planar_tracks

SCENARIO = "turning_vortex"


def quantity_rows(records: list[dict]) -> list[dict]:
    """The result file's rows of coefficient records (:func:`ensemble_coefficients`'), printed."""
    rows = []
    for row in records:
        width = (row["hi"] - row["lo"]) / abs(row["true"])
        entry = {
            "name": row["name"],
            "true": row["true"],
            "median": row["value"],
            "lo": row["lo"],
            "hi": row["hi"],
            "rel_error": row["rel_error"],
            "rel_width": width,
            "inside": bool(row["inside"]),
        }
        if "band_holds" in row and row["band_holds"] == row["band_holds"]:
            entry["band_holds"] = row["band_holds"]
        rows.append(entry)
        extra = f", pointwise band holds {100 * entry['band_holds']:.0f} %" if "band_holds" in entry else ""
        print(
            f"{row['name']:>8}: median {row['value']:.5g} (true {row['true']:.5g}, error "
            f"{100 * row['rel_error']:.2f} %), interval width {100 * width:.2f} % of the truth, "
            f"{'holds' if entry['inside'] else 'MISSES'} the truth{extra}"
        )
    return rows


def member_forecasts(members: list[dict]) -> list[dict]:
    """Each member's RMSE of position and heading at 5 s on the test split, printed."""
    forecasts = [
        {"member": m["member"], **{k: m["forecast"][k] for k in ("rmse_pos", "rmse_heading", "diverged")}}
        for m in members
    ]
    for f in forecasts:
        print(f"{f['member']}: RMSE(pos) at 5 s {f['rmse_pos']:.3g} m, heading {f['rmse_heading']:.3g} rad")
    return forecasts


def track_fitted(folder: Path, fits: list, trained_on: PlanarDataset, truth: PlanarDataset) -> dict:
    """Each member fitted to the observed poses of its own bootstrap (the track fit's defaults),
    and the fitted members' intervals and forecasts."""
    seeds = read_seeds(folder)
    models, runs = [], []
    for seed, fit in zip(seeds, fits, strict=True):
        tracks = fit_planar_tracks(fit.model, bootstrap_planar(trained_on, seed), PlanarTrackConfig())
        models.append(tracks.model)
        runs.append(
            {
                "member": f"seed-{seed}",
                "kept": tracks.kept,
                "val_before": tracks.val_before,
                "val_after": tracks.val_after,
                "objective_first": tracks.history[0],
                "objective_last": tracks.history[-1],
                "seconds": tracks.seconds,
            }
        )
        print(
            f"seed-{seed} track fit: objective {tracks.history[0]:.4g} -> {tracks.history[-1]:.4g}, "
            f"validation misfit {tracks.val_before:.4g} -> {tracks.val_after:.4g}, "
            f"{'kept' if tracks.kept else 'rejected'} ({tracks.seconds:.0f} s)",
            flush=True,
        )
    print("after the track fit:")
    records, _ = ensemble_coefficients(models, truth)
    rows = quantity_rows(records)
    members = [
        {"member": r["member"], **evaluate_turning(m, trained_on)} for r, m in zip(runs, models, strict=True)
    ]
    return {
        "config": dataclasses.asdict(PlanarTrackConfig()),
        "fits": runs,
        "quantities": rows,
        "held": sum(r["inside"] for r in rows),
        "forecasts": member_forecasts(members),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-seed", type=int, required=True)
    parser.add_argument("--obs-noise", type=float, default=1e-3)
    parser.add_argument("--members", type=int, default=3)
    parser.add_argument(
        "--table", action="store_true", help="noise on the observed poses only, imported as a user's table"
    )
    parser.add_argument(
        "--track-fit",
        action="store_true",
        help="also fit each member to its bootstrap's observed poses (fhnn.training.planar_tracks, "
        "its defaults) and report the fitted members' intervals beside the one-step ones",
    )
    args = parser.parse_args()
    record = stamp()
    start = time.perf_counter()
    imported = None
    if args.table:
        clean = simulate_turning(SCENARIO, seed=args.data_seed, obs_noise=0.0)
        columns = observed_table(
            clean, position_noise=args.obs_noise, heading_noise=args.obs_noise, seed=args.data_seed
        )
        body = {"mass": clean.mass, "inertia": clean.inertia, "x_g": clean.x_g}
        imported = import_turning(pd.DataFrame(columns), **body, seed=0)
        # the import with the simulator's truth beside it, for the comparison only
        data = dataclasses.replace(imported, params=clean.params)
        estimated = float(imported.obs_noise)
        print(f"imported: position noise estimated {estimated:.3g} m (given {args.obs_noise:g})", flush=True)
    else:
        data = simulate_turning(SCENARIO, seed=args.data_seed, obs_noise=args.obs_noise)
    trained_on = imported or data  # what the members see; ``data`` carries the truth beside it

    def progress(phase: str, step: int, steps: int, loss: float) -> None:
        if step % 1000 == 0 or step == steps:
            print(f"  {phase} {step}/{steps} train loss {loss:.3e}", flush=True)

    noise = "" if args.obs_noise == 1e-3 else f"_noise{args.obs_noise:g}"
    name = f"turning_intervals_seed{args.data_seed}{noise}{'_table' if args.table else ''}"
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "ens"
        fits = train_turning_ensemble(trained_on, folder, members=args.members, progress=progress)
        found = inspect_turning_ensemble(folder, data)
        members = evaluate_turning_ensemble(folder, trained_on)
        rows = quantity_rows(found.coefficients.to_dict("records"))
        forecasts = member_forecasts(members)
        held = sum(r["inside"] for r in rows)
        print(f"the 90 % intervals hold the truth for {held} of {len(rows)} quantities on this data set")
        result = {
            **record,
            "scenario": SCENARIO,
            "data_seed": args.data_seed,
            "seed_role": seed_role("turning_intervals", args.data_seed),
            "obs_noise": args.obs_noise,
            "route": "table" if args.table else "states",
            "members": args.members,
            "level": 0.9,
            "quantities": rows,
            "held": held,
            "forecasts": forecasts,
            "wall_seconds": time.perf_counter() - start,
        }
        write(RESULTS / f"{name}.json", result)
        if args.track_fit:
            tracked = track_fitted(folder, fits, trained_on, data)
            print(f"after the track fit the intervals hold the truth for {tracked['held']} of {len(rows)}")
            result |= {"track_fit": tracked, "wall_seconds": time.perf_counter() - start}
            write(RESULTS / f"{name}_tracks.json", result)


def write(path: Path, result: dict) -> None:
    """Write a result file and say so."""
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {path}", flush=True)


if __name__ == "__main__":
    main()
