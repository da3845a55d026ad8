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

    python benchmarks/turning_intervals.py --data-seed 20 [--obs-noise 0.001] [--members 3]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, seed_role, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.api.planar import simulate_turning
from fhnn.api.planar_ensemble import (
    evaluate_turning_ensemble,
    inspect_turning_ensemble,
    train_turning_ensemble,
)

SCENARIO = "turning_vortex"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-seed", type=int, required=True)
    parser.add_argument("--obs-noise", type=float, default=1e-3)
    parser.add_argument("--members", type=int, default=3)
    args = parser.parse_args()
    record = stamp()
    start = time.perf_counter()
    data = simulate_turning(SCENARIO, seed=args.data_seed, obs_noise=args.obs_noise)

    def progress(phase: str, step: int, steps: int, loss: float) -> None:
        if step % 1000 == 0 or step == steps:
            print(f"  {phase} {step}/{steps} train loss {loss:.3e}", flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "ens"
        train_turning_ensemble(data, folder, members=args.members, progress=progress)
        found = inspect_turning_ensemble(folder, data)
        members = evaluate_turning_ensemble(folder, data)
    rows = []
    for row in found.coefficients.to_dict("records"):
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
    forecasts = [
        {"member": m["member"], **{k: m["forecast"][k] for k in ("rmse_pos", "rmse_heading", "diverged")}}
        for m in members
    ]
    for f in forecasts:
        print(f"{f['member']}: RMSE(pos) at 5 s {f['rmse_pos']:.3g} m, heading {f['rmse_heading']:.3g} rad")
    held = sum(r["inside"] for r in rows)
    print(f"the 90 % intervals hold the truth for {held} of {len(rows)} quantities on this data set")
    result = {
        **record,
        "scenario": SCENARIO,
        "data_seed": args.data_seed,
        "seed_role": seed_role("turning_intervals", args.data_seed),
        "obs_noise": args.obs_noise,
        "members": args.members,
        "level": 0.9,
        "quantities": rows,
        "held": held,
        "forecasts": forecasts,
        "wall_seconds": time.perf_counter() - start,
    }
    noise = "" if args.obs_noise == 1e-3 else f"_noise{args.obs_noise:g}"
    name = f"turning_intervals_seed{args.data_seed}{noise}"
    path = RESULTS / f"{name}.json"
    path.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
