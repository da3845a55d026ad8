"""Where a default run's time goes: one ``fhnn train`` with no options on the own-data
benchmark's table (``benchmarks/own_data.py``'s recipe, a choosing data seed), with timers
around the whole-track fit's parts — its Levenberg–Marquardt steps and their normal equations,
the rescoring of the validation tracks and the forecast guard, the validation windows.

    python benchmarks/default_run_profile.py [--data-seed 0] [--out DIR]

Prints the training's wall time and each part's total and count. Run it alone: it times.
"""

from __future__ import annotations

import argparse
import collections
import time
from pathlib import Path

import own_data
from _common import check_choosing_seed

import fhnn
from fhnn.training import tracks, trainer


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("benchmarks/_profile"))
    args = p.parse_args()
    check_choosing_seed("own_data", args.data_seed)
    total: dict[str, float] = collections.defaultdict(float)
    count: collections.Counter[str] = collections.Counter()

    def timed(cls: type, name: str, label: str) -> None:
        inner = getattr(cls, name)

        def wrapper(*a, **k):
            start = time.perf_counter()
            out = inner(*a, **k)
            total[label] += time.perf_counter() - start
            count[label] += 1
            return out

        setattr(cls, name, wrapper)

    timed(tracks.TrackFit, "step", "Levenberg–Marquardt steps")
    timed(tracks.TrackFit, "_normal_equations", "  of which normal equations")
    timed(tracks.TrackFit, "rescore", "rescoring (validation tracks, forecast histories)")
    timed(tracks.TrackFit, "_fit_starts", "  start states fitted (Gauss–Newton, everywhere)")
    timed(tracks.TrackFit, "__init__", "whole-track fits set up")
    timed(tracks.ForecastScore, "__call__", "forecast guard (with its rescoring)")
    timed(trainer.Trainer, "validate", "validation windows")
    timed(trainer.Trainer, "track_fit", "whole-track phase")
    args.out.mkdir(parents=True, exist_ok=True)
    _, _, _, data, took = own_data.make_data(args.out, args.data_seed)
    print(f"import {took:.1f} s", flush=True)
    folder = args.out / f"run_seed{args.data_seed}"
    start = time.perf_counter()
    fhnn.train(str(data), str(folder), progress=False)
    print(f"train {time.perf_counter() - start:.1f} s")
    for label in total:
        print(f"  {label:52s} {total[label]:7.1f} s  ({count[label]} calls)")


if __name__ == "__main__":
    main()
