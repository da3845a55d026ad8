"""Forecasts of a turning body from observed tracks (``fhnn turning predict``): each track of a
history table continued from its last estimated state, its last logged forcing held.

::

    from fhnn.api.planar_predict import predict_turning

    forecast = predict_turning("runs/ship", "today.csv", 60.0)   # pandas.DataFrame
    forecast[["traj_id", "t", "x", "y", "heading"]]

The history is read and smoothed as :func:`fhnn.api.planar.import_turning` reads and smooths a
table (the same smoother and noise estimate, over all its tracks together), so the start state
is the import's estimate at each track's last sample: its observed-and-smoothed pose and the
body-frame velocity. What drives the body after it is not in the table; the forecast holds the
last row's forces (a known-force run) or controls (a run of logged controls) constant.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
import numpy as np
import pandas as pd

from fhnn.api.planar import load_turning
from fhnn.api.planar_controls_files import is_controlled_run, load_controlled
from fhnn.data.derivatives import choose_smoother
from fhnn.data.planar import solve_planar
from fhnn.data.planar_controls import controls_as_forcing
from fhnn.data.planar_table import PlanarTrajectory, _smoothed, read_planar_table
from fhnn.data.table import check_table_name, parse_columns, write_table
from fhnn.errors import ConfigError
from fhnn.evaluation.planar import ROLLOUT_BOUND, ROLLOUT_TOL
from fhnn.files import check_output_path

#: The forecast's columns, in order.
COLUMNS = ("traj_id", "t", "x", "y", "heading", "u", "v", "r")
#: The most output steps per track.
MAX_STEPS = 100_000


def _end_forces(track: PlanarTrajectory, heading: float) -> np.ndarray:
    """The body-frame force and moment of a track's last row, ``(3,)`` [N, N, N·m] (zero without
    forcing columns)."""
    if track.body_force is not None:
        return np.asarray(track.body_force[-1], float)
    if track.world_force is not None:
        fx, fy = track.world_force[-1]
        c, s = np.cos(heading), np.sin(heading)
        return np.array([c * fx + s * fy, -s * fx + c * fy, 0.0])
    return np.zeros(3)


def predict_turning(
    run: str | os.PathLike[str],
    history: Any,
    duration: float,
    *,
    dt: float | None = None,
    smoother: str = "auto",
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
    output: str | os.PathLike[str] | None = None,
) -> pd.DataFrame:
    """Continue each track of ``history`` for ``duration`` [s] with the model in ``run``.

    Args:
        run: the folder ``fhnn turning train`` wrote (known forces or logged controls).
        history: a .csv or .parquet path or a ``pandas.DataFrame`` with ``traj_id, t, x, y,
            heading`` [–, s, m, m, rad] and the run's forcing columns (``Fu, Fv[, Mz]`` or ``Fx,
            Fy``; for a run of controls, its control columns), as ``fhnn import`` takes them.
        duration: forecast length [s] after each track's last sample.
        dt: output step [s]; default the history's median sampling interval.
        smoother, columns, time_unit: as :func:`fhnn.api.planar.import_turning`.
        output: a .csv or .parquet file to write the forecast to as well (whole or not at all).

    Returns:
        One row per track and output time: ``traj_id``, ``t`` [s, the table's clock in seconds,
        starting at the track's last sample], the pose ``x, y, heading`` [m, m, rad] and the
        body-frame velocity ``u, v, r`` [m/s, m/s, rad/s]; a forecast that diverged ends where
        it did.

    Raises:
        ConfigError: a bad ``duration``, ``dt`` or setting, or ``output`` not a .csv or .parquet
            name.
        DataFormatError: a bad run folder or table, or an ``output`` that cannot be written.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise ConfigError(f"duration must be a positive number of seconds, got {duration!r}")
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"dt must be a positive number of seconds, got {dt!r}")
    if output is not None:  # before any work: a name write_table takes, in a writable folder
        check_output_path(check_table_name(output))
    if is_controlled_run(run):
        model, controls = load_controlled(run)
        table = read_planar_table(
            controls_as_forcing(history, controls, parse_columns(columns)), time_unit=time_unit
        )
    else:
        model = load_turning(run)
        table = read_planar_table(history, columns=parse_columns(columns), time_unit=time_unit)
    tracks = table.trajectories  # each of at least 3 samples (read_planar_table)
    step = float(np.median(np.concatenate([np.diff(track.t) for track in tracks]))) if dt is None else dt
    n = int(np.floor(duration / step + 1e-9))
    if not 1 <= n <= MAX_STEPS:
        raise ConfigError(f"duration / dt gives {n} output steps; give 1 to {MAX_STEPS:,}")
    poses, rates, _, _ = _smoothed(tracks, choose_smoother(smoother, sum(track.t.size for track in tracks)))
    starts, forces = [], []
    for track, pose, rate in zip(tracks, poses, rates, strict=True):
        psi = pose[-1, 2]
        c, s = np.cos(psi), np.sin(psi)
        nu = np.array([c * rate[-1, 0] + s * rate[-1, 1], -s * rate[-1, 0] + c * rate[-1, 1], rate[-1, 2]])
        starts.append(np.concatenate([pose[-1], nu]))
        forces.append(_end_forces(track, psi))
    ends = np.array([track.t[-1] for track in tracks])
    times = ends[:, None] + step * np.arange(n + 1)[None, :]
    held = np.repeat(np.asarray(forces)[:, None, :], n + 1, axis=1)
    states, _ = solve_planar(
        model,
        jnp.asarray(np.asarray(starts)),
        jnp.zeros((len(tracks), 3, 3, 3)),
        jnp.asarray(times),
        jnp.asarray(held),
        tol=ROLLOUT_TOL,
        bound=ROLLOUT_BOUND,
    )
    states = np.asarray(states)
    rows = []
    for i, track in enumerate(tracks):
        finite = np.all(np.isfinite(states[i]), axis=1)
        keep = int(np.argmin(finite)) if not finite.all() else finite.size
        part = pd.DataFrame(states[i, :keep], columns=list(COLUMNS[2:]))
        part.insert(0, "t", times[i, :keep])
        part.insert(0, "traj_id", track.traj_id)
        rows.append(part)
    forecast = pd.concat(rows, ignore_index=True)
    if output is not None:
        write_table({name: forecast[name].to_numpy() for name in COLUMNS}, output)
    return forecast


__all__ = ["COLUMNS", "predict_turning"]
