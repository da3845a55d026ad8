"""Forecasts of a turning body from observed tracks (``fhnn turning predict``), each started from
the state the model fits to the track's last seconds.

::

    from fhnn.api.planar_forecast import forecast_turning

    forecast = forecast_turning("runs/ship", "today.csv", 60.0)   # pandas.DataFrame
    forecast[["traj_id", "t", "x", "y", "heading"]]

The history is read and smoothed as :func:`fhnn.api.planar.import_turning` reads and smooths a
table. With ``fit_window`` > 0 (the default), each track's state at the start of its last
``fit_window`` seconds is fitted by the model to the poses observed there
(:func:`fhnn.evaluation.planar_start.fit_start_states`, from the smoothed estimate, each
residual over the import's noise estimate) and carried by the model to the track's last sample;
with ``fit_window`` = 0 the forecast starts from the smoothed estimate at the last sample, as
:func:`fhnn.api.planar_predict.predict_turning` does. What drives the body after the history is
not in the table: the forecast holds the last row's forces (a known-force run) or controls (a
run of logged controls) constant. An ensemble's members each fit and forecast; the rows give
their median and a 90 % interval.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from typing import Any

import jax.numpy as jnp
import numpy as np
import pandas as pd

from fhnn.api.defaults import FIT_WINDOW
from fhnn.api.planar import load_turning
from fhnn.api.planar_controls_files import is_controlled_run, load_controlled
from fhnn.api.planar_ensemble import is_turning_ensemble
from fhnn.api.planar_predict import COLUMNS, MAX_STEPS
from fhnn.data.derivatives import choose_smoother
from fhnn.data.planar import solve_planar
from fhnn.data.planar_controls import controls_as_forcing
from fhnn.data.planar_table import PlanarTrajectory, _padded, _smoothed, read_planar_table
from fhnn.data.table import check_table_name, parse_columns, write_table
from fhnn.errors import ConfigError
from fhnn.evaluation.planar import ROLLOUT_BOUND, ROLLOUT_TOL
from fhnn.evaluation.planar_start import fit_start_states
from fhnn.files import check_output_path
from fhnn.training.ensemble import interval, member_folders

#: The least noise levels, position [m] and heading [rad], a start is fitted with: the import's
#: estimate needs five samples a track and is 0 below that.
NOISE_FLOOR = (1e-6, 1e-6)


def _to_body(heading, a, b) -> tuple:
    """The world-frame vector with components ``a`` (along x) and ``b`` (along y) in the body
    frame of ``heading`` [rad], counter-clockwise from x: its forward and port components (the
    same unit; arrays broadcast)."""
    c, s = np.cos(heading), np.sin(heading)
    return c * a + s * b, -s * a + c * b


def _body_forces(track: PlanarTrajectory, heading: np.ndarray) -> np.ndarray:
    """A track's body-frame forces and moment at its samples, ``(n, 3)`` [N, N, N·m]: the
    table's, or its world-frame forces turned by ``heading`` ``(n,)`` [rad], or zero."""
    if track.body_force is not None:
        return np.asarray(track.body_force, float)
    if track.world_force is not None:
        fx, fy = track.world_force[:, 0], track.world_force[:, 1]
        return np.stack([*_to_body(heading, fx, fy), np.zeros_like(fx)], axis=1)
    return np.zeros((track.t.size, 3))


def _state(pose: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """The state ``x, y, ψ, u, v, r`` of a smoothed pose ``(3,)`` and its world-frame rate ``(3,)``."""
    return np.array([*pose, *_to_body(pose[2], rate[0], rate[1]), rate[2]])


def _end_states(
    model,
    tracks: list[PlanarTrajectory],
    poses: list[np.ndarray],
    rates: list[np.ndarray],
    noise: tuple[float, float],
    fit_window: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Each track's state at its last sample, ``(N, 6)``, and its body-frame forcing there,
    ``(N, 3)``: the smoothed estimate (``fit_window`` 0), or the model's state fitted to the
    samples of the last ``fit_window`` seconds (at least the last three) and carried to the end.
    A track whose fitted rollout does not reach its end keeps the smoothed estimate, with a
    warning."""
    forces = [_body_forces(track, pose[:, 2]) for track, pose in zip(tracks, poses, strict=True)]
    ends = np.array([_state(pose[-1], rate[-1]) for pose, rate in zip(poses, rates, strict=True)])
    last_forces = np.array([f[-1] for f in forces])
    if fit_window == 0:
        return ends, last_forces
    cuts = [
        min(int(np.searchsorted(track.t, track.t[-1] - fit_window - 1e-9)), track.t.size - 3)
        for track in tracks
    ]
    size = max(track.t.size - cut for track, cut in zip(tracks, cuts, strict=True))
    windows = [slice(cut, None) for cut in cuts]
    t = _padded([tr.t[w] for tr, w in zip(tracks, windows, strict=True)], size, times=True)
    observed_pose = _padded([tr.pose[w] for tr, w in zip(tracks, windows, strict=True)], size)
    forcing = _padded([f[w] for f, w in zip(forces, windows, strict=True)], size)
    lengths = np.array([tr.t.size - cut for tr, cut in zip(tracks, cuts, strict=True)])
    observed = np.arange(size)[None, :] < lengths[:, None]
    # a history of at most four samples a track has no noise estimate (0): floor it
    floored = (max(noise[0], NOISE_FLOOR[0]), max(noise[1], NOISE_FLOOR[1]))
    _, rollout = fit_start_states(
        model,
        np.array([_state(p[c], r[c]) for p, r, c in zip(poses, rates, cuts, strict=True)]),
        t,
        observed_pose,
        forcing,
        np.zeros((len(tracks), 3, 3, 3)),
        floored,
        observed=observed,
    )
    fitted_ends = rollout[np.arange(len(tracks)), lengths - 1]
    failed = ~np.all(np.isfinite(fitted_ends), axis=1)
    if failed.any():
        names = ", ".join(str(tracks[i].traj_id) for i in np.flatnonzero(failed))
        warnings.warn(
            f"the fitted start's rollout diverged for track(s) {names}; "
            "they start from the smoothed estimate at their last sample",
            UserWarning,
            stacklevel=3,
        )
    return np.where(failed[:, None], ends, fitted_ends), last_forces


def _forecast_one(model, tracks, smoothed, fit_window: float, step: float, n: int) -> pd.DataFrame:
    """One model's forecast rows (:data:`~fhnn.api.planar_predict.COLUMNS`) of every track."""
    poses, rates, noise_pos, noise_psi = smoothed
    starts, held_forces = _end_states(model, tracks, poses, rates, (noise_pos, noise_psi), fit_window)
    ends = np.array([track.t[-1] for track in tracks])
    times = ends[:, None] + step * np.arange(n + 1)[None, :]
    held = np.repeat(held_forces[:, None, :], n + 1, axis=1)
    states, _ = solve_planar(
        model,
        jnp.asarray(starts),
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
    return pd.concat(rows, ignore_index=True)


def _combined(forecasts: list[pd.DataFrame]) -> dict[str, np.ndarray]:
    """The members' forecasts where every one reached: per row their median and, per quantity,
    a 90 % interval ``_lo``, ``_hi`` (:func:`~fhnn.training.ensemble.interval`)."""
    keys = ["traj_id", "t"]
    common = forecasts[0][keys]
    for f in forecasts[1:]:
        common = common.merge(f[keys], on=keys)
    aligned = [common.merge(f, on=keys, how="left") for f in forecasts]
    out: dict[str, np.ndarray] = {k: common[k].to_numpy() for k in keys}
    for name in COLUMNS[2:]:
        median, lo, hi = interval(np.stack([a[name].to_numpy() for a in aligned]))
        out |= {name: median, f"{name}_lo": lo, f"{name}_hi": hi}
    return out


def forecast_turning(
    run: str | os.PathLike[str],
    history: Any,
    duration: float,
    *,
    fit_window: float = FIT_WINDOW,
    dt: float | None = None,
    smoother: str = "auto",
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
    output: str | os.PathLike[str] | None = None,
) -> pd.DataFrame:
    """Continue each track of ``history`` for ``duration`` [s] with the model (or ensemble) in
    ``run``, from the state it fits to the track's last ``fit_window`` seconds.

    Args:
        run: a folder ``fhnn turning train`` wrote (known forces or logged controls, one model
            or an ensemble).
        history: a .csv or .parquet path or a ``pandas.DataFrame`` with ``traj_id, t, x, y,
            heading`` [–, s, m, m, rad] and the run's forcing columns (``Fu, Fv[, Mz]`` or ``Fx,
            Fy``; for a run of controls, its control columns), as ``fhnn import`` takes them.
        duration: forecast length [s] after each track's last sample.
        fit_window: the seconds before each track's last sample whose observed poses the start
            state is fitted to (at least the last three samples); 0: start from the smoothed
            estimate at the last sample.
        dt: output step [s]; default the history's median sampling interval.
        smoother, columns, time_unit: as :func:`fhnn.api.planar.import_turning`.
        output: a .csv or .parquet file to write the forecast to as well (whole or not at all).

    Returns:
        One row per track and output time: ``traj_id``, ``t`` [s, the table's clock in seconds,
        starting at the track's last sample], the pose ``x, y, heading`` [m, m, rad] and the
        body-frame velocity ``u, v, r`` [m/s, m/s, rad/s]; a forecast that diverged ends where
        it did. An ensemble's rows are its members' median, each quantity with ``_lo`` and
        ``_hi``, the 5th and 95th percentiles, where every member's forecast reached.

    Raises:
        ConfigError: a bad ``duration``, ``fit_window``, ``dt`` or setting, or ``output`` not a
            .csv or .parquet name.
        DataFormatError: a bad run folder or table, or an ``output`` that cannot be written.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise ConfigError(f"duration must be a positive number of seconds, got {duration!r}")
    if not (np.isfinite(fit_window) and fit_window >= 0):
        raise ConfigError(f"fit_window must be zero or a positive number of seconds, got {fit_window!r}")
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"dt must be a positive number of seconds, got {dt!r}")
    if output is not None:  # before any work: a name write_table takes, in a writable folder
        check_output_path(check_table_name(output))
    ensemble = is_turning_ensemble(run)
    folders = member_folders(run) if ensemble else [run]
    if is_controlled_run(folders[0]):
        loaded = [load_controlled(folder) for folder in folders]
        models = [model for model, _ in loaded]
        table = read_planar_table(
            controls_as_forcing(history, loaded[0][1], parse_columns(columns)), time_unit=time_unit
        )
    else:
        models = [load_turning(folder) for folder in folders]
        table = read_planar_table(history, columns=parse_columns(columns), time_unit=time_unit)
    tracks = table.trajectories  # each of at least 3 samples (read_planar_table)
    step = float(np.median(np.concatenate([np.diff(track.t) for track in tracks]))) if dt is None else dt
    n = int(np.floor(duration / step + 1e-9))
    if not 1 <= n <= MAX_STEPS:
        raise ConfigError(f"duration / dt gives {n} output steps; give 1 to {MAX_STEPS:,}")
    smoothed = _smoothed(tracks, choose_smoother(smoother, sum(track.t.size for track in tracks)))
    forecasts = [_forecast_one(m, tracks, smoothed, fit_window, step, n) for m in models]
    columns_out = _combined(forecasts) if ensemble else {k: forecasts[0][k].to_numpy() for k in COLUMNS}
    if output is not None:
        write_table(columns_out, output)
    return pd.DataFrame(columns_out)


__all__ = ["FIT_WINDOW", "forecast_turning"]
