"""``fhnn.predict``: forecasts from a trained run or ensemble, as ``fhnn predict``."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.api.fit import Fit, load_runs
from fhnn.data.cleaning import OUTLIER_SIGMAS, drop_table_outliers
from fhnn.data.clock import SECONDS_ONLY, seconds_to_date_times
from fhnn.data.table import (
    Table,
    check_forcing_hold,
    check_table_name,
    held,
    parse_columns,
    read_forcing,
    read_table,
    shift_times,
    write_table,
)
from fhnn.errors import ConfigError
from fhnn.evaluation import predict as prediction
from fhnn.evaluation.predict import FIT_WINDOW, SAMPLES, BandCheck, Forecast, band_scale, band_tracks, widened
from fhnn.files import check_output_path
from fhnn.models.base import AbstractVectorField
from fhnn.training.ensemble import INTERVAL


@dataclass
class Prediction:
    """A forecast.

    Attributes:
        columns: ``traj_id, t, x, y, vx, vy`` [–, s, m, m, m/s, m/s] and, with a band, ``x_lo,
            x_hi, …`` (5th and 95th percentiles); ``t`` on the clock of the run's data.
        forecast: the underlying :class:`~fhnn.evaluation.predict.Forecast`.
        notes: what is worth saying about it (no forcing, dropped glitches, the fit's residual).
        warnings: what went wrong (diverged forecasts).
    """

    columns: dict[str, np.ndarray]
    forecast: Forecast
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def to_pandas(self) -> Any:
        """:attr:`columns` as a ``pandas.DataFrame``."""
        import pandas as pd

        return pd.DataFrame(self.columns)

    def rows(self) -> list[str]:
        """The forecast as CSV lines, the header first."""
        names = list(self.columns)
        lines = [",".join(names)]
        for row in zip(*(self.columns[c] for c in names), strict=True):
            lines.append(",".join(str(v) if isinstance(v, str) else repr(float(v)) for v in row))
        return lines


def predict(
    run: Fit | str | os.PathLike[str],
    duration: float,
    *,
    initial: Sequence[float] | None = None,
    t0: float = 0.0,
    history: Table | Any | None = None,
    forcing: Any | None = None,
    forcing_hold: str = "linear",
    dt: float | None = None,
    fit_window: float | None = None,
    samples: int = SAMPLES,
    outliers: float | None = OUTLIER_SIGMAS,
    output: str | os.PathLike[str] | None = None,
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
    check: bool = True,
) -> Prediction:
    """Forecast with a trained model from a given state or from the end of observed tracks.

    Times [s] are on the clock of the table the run's data came from, for every argument.

    Args:
        run: a :class:`~fhnn.api.fit.Fit`, or a run or ensemble folder (a vector-field model).
        duration: forecast length [s].
        initial, t0: a start state ``x, y, vx, vy`` [m, m/s] and its time [s].
        history: observed tracks (a path, ``pandas.DataFrame`` or table, columns as for
            :func:`fhnn.import_table`), each forecast from its state fitted to its last
            ``fit_window`` [s] (default 1), with ``outliers`` as for the import.
        forcing, forcing_hold: known forces over the forecast (``t, Fx, Fy[, traj_id]``) [s, N],
            ``"linear"`` between rows or ``"previous"`` (held until the next row); default none.
        dt: output step [s] (default: the history's median step, or 0.05).
        samples, output: start states drawn from each fit's uncertainty and forecast for the
            band; a .csv or .parquet file to write the forecast to as well.
        columns, time_unit: the tables' names of our columns and unit of numeric times, as for
            :func:`fhnn.import_table`.
        check: check the band on the validation tracks (:func:`check_band`) and widen it where it
            holds fewer observations than it claims.

    Returns:
        The :class:`Prediction`; with a band (an ensemble, or a history) ``x, y, …`` are the
        median and ``x_lo, x_hi, …`` the 5th and 95th percentiles, widened as the check says.

    Raises:
        ConfigError: neither or both of ``initial`` and ``history``, bad values, or a model that
            is not a vector field.
        DataFormatError: an unreadable table or run.
    """
    if (initial is None) == (history is None):
        raise ConfigError("give --initial x,y,vx,vy or --history TABLE (one of them)")
    mapping = parse_columns(columns)
    check_forcing_hold(forcing_hold)  # refused with or without --forcing
    if output is not None:
        check_output_path(Path(output))
        check_table_name(output)
    fit = run if isinstance(run, Fit) else None
    runs = fit.runs if fit is not None else load_runs(run)
    models = []
    for r in runs:
        if not isinstance(r.state.best_model, AbstractVectorField):  # type: ignore[union-attr]
            raise ConfigError(f"predict needs a vector-field model; a {r.kind!r} model steps on its own grid")
        models.append(r.state.best_model)  # type: ignore[union-attr]
    notes: list[str] = []
    # every time given is on the clock of the table the run's data came from; the model's t = 0
    # is that clock's `offset` (the imported table's first sample)
    clock = runs[-1].clock()
    origin, offset = clock["origin"], clock["offset"]
    if "unknown" in clock:
        notes.append(
            f"note: the clock of the table behind {fit.folder if fit else run} is unknown — "
            f"{clock['unknown']}: times are read as the model's own (its t = 0 the table's first sample)"
        )
    read_origin = SECONDS_ONLY if origin is None else origin
    tracks = (
        history
        if isinstance(history, Table) or history is None
        else read_table(history, read_origin, mapping, time_unit)
    )
    glitches = 0
    if tracks is not None:
        tracks, glitches = drop_table_outliers(tracks, outliers)
    forces = (
        held(read_forcing(forcing, read_origin, mapping, time_unit), forcing_hold)
        if forcing is not None
        else None
    )
    dates = tracks is not None and tracks.time_origin is not None
    if offset:
        if tracks is not None:
            tracks = shift_times(tracks, -offset)
        if forces is not None:
            forces = {k: (t - offset, f) for k, (t, f) in forces.items()}
    if dt is None:
        dt = (
            float(np.median(np.concatenate([np.diff(tr.t) for tr in tracks.trajectories])))
            if tracks
            else 0.05
        )
    forecasts = [
        prediction.predict_tracks(
            model,
            duration=duration,
            dt=dt,
            initial=None if initial is None else np.asarray(initial, dtype=float),
            t0=t0 - offset,
            history=tracks,
            forcing_table=forces,
            fit_window=FIT_WINDOW if fit_window is None else fit_window,
            samples=samples,
        )
        for model in models
    ]
    banded = len(forecasts) > 1 or forecasts[0].samples is not None
    result = Forecast.of_ensemble(forecasts, INTERVAL) if banded else forecasts[0]
    if banded and check:
        # the runs are loaded already: the fit takes them and their data set
        result = _checked(
            result, fit if fit is not None else Fit(runs, runs[0].dataset(), Path(run)), samples, notes
        )
    notes += _notes(forces is None, glitches, outliers, tracks is not None, result)
    warnings = []
    failed = [i for i, ok in zip(result.ids, result.ok, strict=True) if not ok]
    if failed:
        warnings.append(f"warning: the forecast of {', '.join(failed)} diverged")
    columns = result.columns()
    columns["t"] = columns["t"] + offset
    if dates:  # the history gave date-times: so does the forecast
        columns["t"] = seconds_to_date_times(columns["t"], origin)
    if output is not None:
        write_table(columns, output)
    return Prediction(columns, result, notes, warnings)


def _checked(result: Forecast, fit: Fit, samples: int, notes: list[str]) -> Forecast:
    """``result``'s band widened as :func:`check_band` says, with a note of what it found."""
    checked = check_band(fit, samples=samples)
    if checked is None:
        notes.append("note: the band is unchecked: fewer than half the validation tracks are 2 s long")
        return result
    notes.append(f"note: {checked.text()} ({BAND_FILE} in the run's folder)")
    return widened(result, checked.scale)


def _notes(unforced: bool, glitches: int, sigmas: float | None, fitted: bool, result: Forecast) -> list[str]:
    notes = []
    if unforced:
        notes.append("note: no --forcing: the forecast assumes no external force")
    if glitches:
        notes.append(
            f"note: {glitches} position(s) of the history lay more than {sigmas:g} noise levels from the "
            "cubic through their neighbours and were left out of the fit (--outliers off keeps them)"
        )
    if fitted:
        notes.append(
            f"fitted {len(result.ids)} track(s): RMS position residual median "
            f"{float(np.median(result.fit_rms)):.3g} m (about the noise when the model explains them)"
        )
    return notes


#: The file in a run's (or ensemble's) folder that keeps :func:`check_band`'s result.
BAND_FILE = "band_check.json"
#: Seconds of each validation track that :func:`check_band` fits, and at most forecasts.
BAND_HISTORY, BAND_HORIZON = FIT_WINDOW, 5.0


def check_band(fit: Fit, *, samples: int = SAMPLES, refresh: bool = False) -> BandCheck | None:
    """How often the forecast band (of an ensemble's members and each one's start-state samples,
    as :func:`predict` makes it) holds the observed positions of the validation tracks: each is
    fitted on its first second and forecast up to 5 s (at most the median track's length less
    that second; shorter tracks sit out; the
    band's percentiles :data:`~fhnn.training.ensemble.INTERVAL`), under the data set's forces;
    the observations' noise (the data set's ``obs_noise``) widens the band in quadrature.

    The result is kept in the fit's folder (:data:`BAND_FILE`) for the weights it was made with.

    Returns:
        The :class:`~fhnn.evaluation.predict.BandCheck`, or ``None`` where fewer than half the
        validation tracks are 2 s long.
    """
    import hashlib
    import json

    weights = [r.folder / "best.eqx" for r in fit.runs]
    stamp = hashlib.sha256(b"".join(w.read_bytes() for w in weights if w.exists())).hexdigest()
    path = fit.folder / BAND_FILE
    if path.exists() and not refresh:
        kept = json.loads(path.read_text())
        if kept.get("weights") == stamp and kept.get("samples") == samples:
            return BandCheck(**kept["check"])
    data = fit.dataset
    split = data.val
    ids = data.extra["import"]["traj_ids"]["val"] if data.imported else [str(i) for i in range(split.n_traj)]
    times = np.broadcast_to(split.times, split.mask.shape)
    lengths = [float(np.ptp(times[i][split.mask[i]])) for i in range(split.n_traj)]
    typical = float(np.median(lengths)) if lengths else 0.0  # at least half the tracks take part
    horizon = min(BAND_HORIZON, typical - BAND_HISTORY)
    if horizon < 1.0:
        return None
    table, rows, later = band_tracks(split, ids, BAND_HISTORY, horizon)
    dt = float(np.median(np.concatenate([np.diff(tr.t) for tr in table.trajectories])))
    forecasts = [
        prediction.predict_tracks(
            model,
            duration=horizon,
            dt=dt,
            history=table,
            forcing_table=rows,
            fit_window=BAND_HISTORY,
            samples=samples,
        )
        for model in fit.models
    ]
    level = (INTERVAL[1] - INTERVAL[0]) / 100.0
    coverage, scale, points = band_scale(
        Forecast.of_ensemble(forecasts, INTERVAL), later, data.obs_noise, level
    )
    check = BandCheck(level, coverage, scale, len(later), points, BAND_HISTORY, horizon)
    path.write_text(
        json.dumps({"weights": stamp, "samples": samples, "check": check.to_dict()}, indent=2) + "\n"
    )
    return check
