"""How many whole-track iterations does a default run need? Chosen on the own-data choosing
seeds' validation tracks, from the history of default runs (``train.track_steps`` 20).

A run with ``train.track_steps=K`` is the first ``K`` iterations of one with 20 (the same
pieces, the same damping path); its model is the last of those iterates the forecast guard
accepted. For each ``K`` of :data:`CANDIDATES` this reads, per data seed, that model's
validation forecast (``val_forecast``: RMS position error of 5 s forecasts of the validation
tracks, as ``fhnn predict`` makes them) and its validation-track misfit
(``val_track_mean_square``: the validation tracks fitted whole from their own start states),
each over the same at ``K`` = 20.

The rule, fixed before the runs it reads were made: the smallest ``K`` whose geometric means
over the choosing seeds are at most :data:`FORECAST_SLACK` (forecast) and
:data:`MISFIT_SLACK` (misfit). Nothing here reads a test split or the simulator's truth.

    python benchmarks/own_data.py --data-seed N --skip-speed --out DIR   # N = 0, 1, 2
    python benchmarks/track_iterations.py --out DIR
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from _common import seeds

#: The iteration counts compared (20 is today's default).
CANDIDATES = (2, 4, 6, 8, 10, 12, 15, 20)
#: Largest accepted ratio of the validation forecast error to that at 20 iterations.
FORECAST_SLACK = 1.01
#: Largest accepted ratio of the validation tracks' mean square misfit to that at 20 iterations.
MISFIT_SLACK = 1.05


def guarded(history: list[dict], k: int) -> dict:
    """The record of the model a run with ``k`` whole-track iterations ends with: its last
    iterate (of the first ``k``) that forecasts the validation tracks no worse than the phase's
    start, or the phase's start values where none does."""
    records = [r for r in history if r.get("phase") == "tracks"][:k]
    start = records[0]["val_forecast_start"]
    kept = [r for r in records if r["val_forecast"] <= start]
    if kept:
        return kept[-1]
    return {"val_forecast": start, "val_track_mean_square": records[0]["val_track_mean_square_start"]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    args = p.parse_args()
    data_seeds = seeds("own_data", "choosing")
    runs = {s: args.out / f"run_seed{s}_defaults" / "run.json" for s in data_seeds}
    histories = {s: json.loads(path.read_text())["history"] for s, path in runs.items()}
    print(f"# own-data choosing seeds {data_seeds}; ratios to 20 iterations (validation splits only)")
    print(f"{'K':>3}  {'forecast (per seed)':<28}{'gmean':>7}   {'misfit (per seed)':<28}{'gmean':>7}")
    chosen = None
    for k in CANDIDATES:
        fr, mr = [], []
        for s in data_seeds:
            end, now = guarded(histories[s], 20), guarded(histories[s], k)
            fr.append(now["val_forecast"] / end["val_forecast"])
            mr.append(now["val_track_mean_square"] / end["val_track_mean_square"])
        gf, gm = float(np.exp(np.mean(np.log(fr)))), float(np.exp(np.mean(np.log(mr))))
        ok = gf <= FORECAST_SLACK and gm <= MISFIT_SLACK
        if ok and chosen is None:
            chosen = k
        cells_f = " ".join(f"{x:.4f}" for x in fr)
        cells_m = " ".join(f"{x:.4f}" for x in mr)
        print(f"{k:>3}  {cells_f:<28}{gf:>7.4f}   {cells_m:<28}{gm:>7.4f}{'  meets the rule' if ok else ''}")
    print(f"chosen: train.track_steps = {chosen}")


if __name__ == "__main__":
    main()
