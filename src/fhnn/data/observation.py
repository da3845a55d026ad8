"""Observations of a data set: the errors a training window starts from, and the table an
instrument would record of a simulation."""

from __future__ import annotations

import numpy as np

from fhnn.data.dataset import SPLITS, Dataset
from fhnn.data.derivatives import derivative_error, noise_level
from fhnn.data.table import COLUMNS
from fhnn.errors import ConfigError


def start_errors(dataset: Dataset) -> tuple[float, float]:
    """``(σ_x [m], σ_v [m/s])``: the noise of ``dataset``'s observed positions and the RMS error of
    its estimated velocities, which a multi-step training window starts from. From the import
    record (``position_noise``, ``velocity_error``), estimated from the positions of every split
    where the record lacks them (a file imported before the record kept the velocity error, or a
    data set without an import record: the spline smoother assumed)."""
    record = dataset.extra.get("import") or {}
    noise, error = record.get("position_noise"), record.get("velocity_error")
    if noise is not None and error is not None:
        return float(noise), float(error)
    series = []
    for name in SPLITS:
        split = dataset[name]
        for i, k in enumerate(split.sample_counts):
            series += [(split.times[i, :k], split.states[i, :k, a]) for a in range(2)]
    if noise is None:
        noise = noise_level(series)
    smoother = record.get("smoother") or "spline"
    return float(noise), derivative_error(series, float(noise), smoother, seed=dataset.seed)


def observe(
    dataset: Dataset,
    *,
    step: float,
    jitter: float = 0.0,
    noise: float = 0.0,
    drop: float = 0.0,
    velocities: bool = False,
    forces: bool = True,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """A table (columns by name, one row per sample, rows shuffled) of what an instrument would
    record of a simulated, finely sampled ``dataset``: every trajectory of every split, sampled
    about every ``step`` s with each interval drawn from ``step·U(1 − jitter, 1 + jitter)`` (the
    nearest stored sample is taken, so the data set's ``dt`` must be much finer than ``step``),
    positions (and velocities when ``velocities``) with Gaussian noise of std ``noise`` [m, m/s],
    the known forces when ``forces``, and a fraction ``drop`` of the rows replaced by gaps (NaN
    positions). The worked example and ``benchmarks/own_data.py`` make their tables so."""
    rng = np.random.default_rng(seed)
    columns: dict[str, list[np.ndarray]] = {c: [] for c in ("traj_id", "t", "x", "y", "vx", "vy", "Fx", "Fy")}
    k = 0
    for name in SPLITS:
        split = dataset[name]
        if not split.regular:
            raise ConfigError("observe() needs a simulated data set (common sample times)")
        t = split.t
        for i in range(split.n_traj):
            draws = step * rng.uniform(1 - jitter, 1 + jitter, int(2 * t[-1] / step) + 2)
            wanted = np.concatenate([[0.0], np.cumsum(draws)])
            idx = np.unique(np.searchsorted(t, wanted[wanted <= t[-1]]).clip(0, t.size - 1))
            clean = split.states_clean[i, idx]
            columns["traj_id"].append(np.full(idx.size, k))
            columns["t"].append(t[idx])
            for j, c in enumerate(("x", "y", "vx", "vy")):
                columns[c].append(clean[:, j] + noise * rng.normal(size=idx.size))
            columns["Fx"].append(split.forces[i, idx, 0])
            columns["Fy"].append(split.forces[i, idx, 1])
            k += 1
    table = {c: np.concatenate(v) for c, v in columns.items()}
    gaps = rng.random(table["t"].size) < drop
    table["x"][gaps] = np.nan
    table["y"][gaps] = np.nan
    keep = [c for c in COLUMNS if (velocities or c not in ("vx", "vy")) and (forces or c not in ("Fx", "Fy"))]
    order = rng.permutation(table["t"].size)
    return {c: table[c][order] for c in keep}
