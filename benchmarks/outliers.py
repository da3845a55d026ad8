"""A tracker's glitches on issue 14's table (``benchmarks/own_data.py``'s data: ``steady_vortex``
with actuation, positions with 1 mm noise about every 0.05 s, 5 % of rows dropped): positions of
a fraction of the rows moved by 2-50 cm in a random direction, then ``fhnn import`` with its
defaults (``--outliers 8``). Prints how many glitches were put in, how many positions the import
dropped, how many of those were glitches and how many glitches stayed; and, on the table without
glitches, the largest residual in noise levels and what the import dropped (nothing, so that the
import is the same as with ``--outliers off``); and what would be dropped of the simulation's
tracks sampled every 0.05-2 s with 1 mm noise, where the motion between samples, not the noise,
makes the residuals (the noise level seen grows with the step).

Usage::

    python benchmarks/outliers.py [--out DIR] [--fraction F] [--seed K]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from own_data import add_glitches, make_data, run_cli

from fhnn.data.cleaning import OUTLIER_SIGMAS, drop_outliers
from fhnn.data.dataset import read_dataset
from fhnn.data.derivatives import lagrange_residuals, noise_level
from fhnn.data.table import Trajectory, write_table


def kept_samples(path: Path) -> set[tuple[str, float]]:
    """``(traj_id, t)`` of every sample of an imported data set, on the table's clock."""
    data = read_dataset(path)
    record = data.extra["import"]
    out = set()
    for name, ids in record["traj_ids"].items():
        split = data[name]
        for i, traj in enumerate(ids):
            times = split.times[i, : split.sample_counts[i]] + record["time_offset"]
            out.update((traj, float(t)) for t in times)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    parser.add_argument("--fraction", type=float, default=0.002)
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the glitches (own_data.py: the data seed)"
    )
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    fine, table, _, data, _ = make_data(args.out, 0)
    record = read_dataset(data).extra["import"]
    residuals = []
    for traj in np.unique(table["traj_id"]):
        rows = np.flatnonzero((table["traj_id"] == traj) & ~np.isnan(table["x"]))
        rows = rows[np.argsort(table["t"][rows])]
        residuals += [np.abs(lagrange_residuals(table["t"][rows], table[c][rows])) for c in ("x", "y")]
    z = np.concatenate(residuals)
    print(
        f"without glitches: {int((~np.isnan(table['x'])).sum())} positions, the largest residual "
        f"{z.max() / record['position_noise']:.1f} noise levels; the import dropped "
        f"{record['outliers_dropped']} as glitches"
    )
    bad, pick = add_glitches(table, args.fraction, args.seed)
    rows = np.flatnonzero(~np.isnan(bad["x"]))
    rng = np.random.default_rng(args.seed)
    path = write_table(bad, args.out / "track_seed0_glitches.csv")
    target = args.out / "track_seed0_glitches.h5"
    target.unlink(missing_ok=True)
    area = str(fine.body_params["A"])
    run_cli("import", str(path), "-o", str(target), "--mass", "10", "--area", area, "-q")
    kept = kept_samples(target)
    glitches = {(str(bad["traj_id"][r]), float(bad["t"][r])) for r in pick}
    every = {(str(bad["traj_id"][r]), float(bad["t"][r])) for r in rows}
    dropped = every - kept
    print(
        f"with glitches of 2-50 cm in {args.fraction:.1%} of the rows ({pick.size}): the import dropped "
        f"{len(dropped)} positions, {len(dropped & glitches)} of them glitches; {len(glitches & kept)} "
        f"glitch(es) stayed; noise seen {read_dataset(target).obs_noise * 1e3:.4f} mm "
        f"(without glitches {record['position_noise'] * 1e3:.4f} mm)"
    )
    for step in (0.05, 0.2, 0.5, 1.0, 2.0):
        every = round(step / fine.dt)
        tracks = [
            Trajectory(f"{name}{i}", t, pos + 1e-3 * rng.normal(size=pos.shape), None, None)
            for name in ("train", "val", "test")
            for t, states in [(fine[name].t[::every], fine[name].states_clean[:, ::every])]
            for i, pos in enumerate(states[..., :2])
        ]
        noise = noise_level([(tr.t, tr.pos[:, k]) for tr in tracks for k in range(2)])
        _, dropped, _ = drop_outliers(tracks, noise, OUTLIER_SIGMAS)
        print(
            f"no glitches, every {step:g} s: {sum(tr.t.size for tr in tracks)} positions, noise seen "
            f"{noise * 1e3:.3f} mm (true 1 mm), dropped {dropped}"
        )


if __name__ == "__main__":
    main()
