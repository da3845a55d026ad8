"""How many samples should the whole-track fit hold? Chosen on the own-data choosing seeds'
validation tracks, from one ``own_data.py`` run per seed and budget (``train.track_samples``).

The default budget, 25,000 samples, holds all 49 training tracks of an own-data table (~20,000
samples); a smaller one keeps a seeded subset of them (:func:`fhnn.training.tracks.track_pieces`)
and each whole-track iteration's forward-mode passes shrink with it. For each budget this reads,
per data seed, the validation forecast that does not depend on the budget: ``own_data.py``'s
``val_forecasts.origins`` (``fhnn predict`` from the first second of a piece starting every 2 s
of each validation track, RMSE(pos) at 5 s against its observations), over the same at the
default.

The rule, fixed in ``benchmarks/seeds.toml`` before the runs it reads were made: the smallest
budget whose geometric mean ratio over the choosing seeds is at most :data:`FORECAST_SLACK`.
Only that ratio chooses. The record keeps beside it each run's training time (two runs shared the
2 cores throughout), the tracks its fit held, and its errors against the simulator's truth
(coefficients, total drag, flow), which choose nothing.

    python benchmarks/own_data.py --data-seed N --skip-speed --out DIR/sN_default
    python benchmarks/own_data.py --data-seed N --skip-speed --out DIR/sN_B --set train.track_samples=B
    python benchmarks/track_budget.py --out DIR        # N = 0, 1, 2; B = 12500, 6250
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from _common import DESIGN_DATA, seeds, stamp

#: The budget of ``fhnn train``'s defaults, then the candidates, largest first.
DEFAULT = 25_000
CANDIDATES = (12_500, 6_250)
#: Largest accepted geometric-mean ratio of the validation forecast to the default's.
FORECAST_SLACK = 1.01


def _run(folder: Path, seed: int, budget: int) -> dict:
    """The scores of ``own_data.py``'s run of data seed ``seed`` at ``budget`` in ``folder``."""
    tag = "defaults" if budget == DEFAULT else f"traintrack_samples{budget}"
    result = json.loads((folder / f"result_seed{seed}_{tag}.json").read_text())
    history = json.loads((folder / f"run_seed{seed}_{tag}" / "run.json").read_text())["history"]
    tracks = [r for r in history if r.get("phase") == "tracks"]
    return {
        "commit": result["commit"],
        "val_forecast_5s": result["val_forecasts"]["origins"]["rmse_pos_vs_observed"]["5"],
        "val_forecasts": result["val_forecasts"]["origins"]["trajectories"],
        "train_seconds": result["train_seconds"],
        "fit_tracks": tracks[0]["tracks"] if tracks else 0,
        "fit_iterations": len(tracks),
        "truth": {
            "coefficients_mean_rel": result["coefficients_mean_rel"],
            "drag_mean_rel": result["drag_mean_rel"],
            "flow_rel_l2": result["flow_rel_l2"],
        },
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="folder of the sN_B run folders")
    args = p.parse_args()
    data_seeds = seeds("own_data", "choosing")
    budgets = (DEFAULT, *CANDIDATES)
    folder = lambda s, b: args.out / f"s{s}_{'default' if b == DEFAULT else b}"  # noqa: E731
    runs = {str(b): {str(s): _run(folder(s, b), s, b) for s in data_seeds} for b in budgets}
    ratios, chosen = {}, DEFAULT
    for b in CANDIDATES:
        score = lambda b, s: runs[str(b)][str(s)]["val_forecast_5s"]  # noqa: E731
        per_seed = [score(b, s) / score(DEFAULT, s) for s in data_seeds]
        gmean = float(np.exp(np.mean(np.log(per_seed))))
        ratios[str(b)] = {"per_seed": per_seed, "gmean": gmean}
        if gmean <= FORECAST_SLACK:
            chosen = b  # candidates run largest first: the last one within the slack is the smallest
    record = {
        **stamp(),
        "benchmark": "own_data",
        "seed_role": "choosing",
        "data_seeds": data_seeds,
        "default": DEFAULT,
        "forecast_slack": FORECAST_SLACK,
        "runs": runs,
        "ratios": ratios,
        "chosen": chosen,
    }
    target = DESIGN_DATA / "track_budget_choosing.json"
    target.write_text(json.dumps(record, indent=1))
    for b, r in ratios.items():
        cells = " ".join(f"{x:.4f}" for x in r["per_seed"])
        print(f"track_samples {b:>6}: validation forecast / default's {cells}, gmean {r['gmean']:.4f}")
    print(f"chosen: train.track_samples = {chosen}; wrote {target}")


if __name__ == "__main__":
    main()
