"""What one iteration of the whole-track fit costs as the data grow, with and without its size
budget (``train.track_samples``, :func:`fhnn.training.tracks.track_pieces`).

``fhnn train`` ends with the whole-track fit where velocities were estimated: Levenberg–Marquardt
on every training track at once, its Jacobian by forward mode, one rollout of every track per
parameter (331 for FHNN at width 64). Its cost grows with the samples it holds; Adam's does not
(a fixed number of steps on batches of windows). This script simulates ``steady_vortex`` tracks
sampled every 0.05 s (as issue 14's tracker), ``--tracks`` of them for each ``--seconds`` given,
builds the default FHNN for them and times one iteration (the Jacobian, the reduced normal
equations and the damped solves; after a first, compiling, iteration) on the whole split and on the
pieces the default budget keeps, and prints the samples each holds and seconds per iteration,
and the whole split's extrapolated to issue 14's import-speed table (1,000 tracks × 2,000 rows,
70 % of them training).

Usage::

    python benchmarks/track_fit_cost.py [--tracks N] [--seconds S ...] [--budget B]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario
from fhnn.training.plans import PLANS
from fhnn.training.run import Run, RunConfig
from fhnn.training.tracks import TrackFit, track_pieces
from fhnn.training.trainer import TrainConfig

#: The paper's run (the ``adam`` plan): what these measurements were taken with.
PAPER_RUN = RunConfig().with_settings(PLANS["adam"].settings("fhnn"))


def iteration_seconds(model, split) -> float:
    """Wall time of one Levenberg–Marquardt iteration on ``split``, after a compiling one."""
    fit = TrackFit(model, model.track_parameters(), split)
    fit.step()
    start = time.perf_counter()
    fit.step()
    return time.perf_counter() - start


def measure(model, split, label: str) -> float:
    """Print ``label`` with ``split``'s size and :func:`iteration_seconds` on it; seconds per
    held sample."""
    sec = iteration_seconds(model, split)
    held = split.n_traj * split.n_times
    size = f"{split.n_traj} tracks x {split.n_times} samples = {held} held"
    print(f"  {label}: {size}, {sec:.1f} s per iteration")
    return sec / held


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tracks", type=int, default=40, help="tracks simulated (70 %% train)")
    p.add_argument("--seconds", type=float, nargs="+", default=[20.0, 60.0], help="track durations [s]")
    p.add_argument("--budget", type=int, default=TrainConfig().track_samples, help="train.track_samples")
    args = p.parse_args()
    sc = get_scenario("steady_vortex")
    print(f"budget (train.track_samples): {args.budget} samples")
    for seconds in args.seconds:
        config = SimulationConfig.for_scenario(
            sc, n_traj=args.tracks, duration=seconds, test_duration=seconds, dt=0.05, seed=0
        )
        ds = simulate_dataset(sc, config)
        with tempfile.TemporaryDirectory() as folder:  # the paper's FHNN (width 64) for these data
            model = Run.create(Path(folder) / "run", ds, PAPER_RUN).skeleton()
        whole = ds.train
        pieces, _ = track_pieces(whole, args.budget, seed=5)
        per_sample = measure(model, whole, f"{seconds:g} s tracks, whole split")
        if pieces is whole:
            print(f"  {seconds:g} s tracks: the split fits the budget; nothing cut")
        else:
            measure(model, pieces, f"{seconds:g} s tracks, within the budget")
        big = 700 * 2000
        minutes = per_sample * big / 60
        print(
            f"  whole split extrapolated to 700 training tracks x 2,000 rows: {minutes:.0f} min "
            f"per iteration, {20 * minutes / 60:.1f} h for the default 20"
        )


if __name__ == "__main__":
    main()
