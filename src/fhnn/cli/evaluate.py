"""``fhnn evaluate`` and ``fhnn predict``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich import box
from rich.table import Table

from fhnn.cli import render
from fhnn.cli.options import (
    ColumnsOption,
    DataArgument,
    ForcingHoldOption,
    RunDirArgument,
    TimeUnitOption,
    app,
)
from fhnn.data.cleaning import OUTLIER_SIGMAS, parse_outliers
from fhnn.errors import ConfigError
from fhnn.evaluation.metrics import METRICS
from fhnn.evaluation.predict import SAMPLES


@app.command()
def evaluate(
    run_dir: RunDirArgument,
    data: DataArgument = None,
    horizons: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated horizons in whole seconds [default: those of 1,2,5,16,60 that the "
            "trajectories last]."
        ),
    ] = None,
    split: Annotated[str, typer.Option(help="train|val|test")] = "test",
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print {horizon: {metric: value}} as strict JSON; an error that is infinite (a "
            'rollout diverged, see diverged_count) is null. On an ensemble: {"mean": …, "std": …, '
            '"members": {seed: …}}.',
        ),
    ] = False,
) -> None:
    """Roll the best model out from each trajectory's first state and report errors at horizons.
    On an ensemble (fhnn train --seeds N): every member, and each error's mean over the members."""
    from fhnn.api.evaluate import evaluate as evaluate_fit

    hs = None
    if horizons is not None:
        try:
            hs = [float(h) for h in horizons.split(",") if h.strip()]
        except ValueError:
            raise ConfigError(f"--horizons expects numbers separated by commas, got {horizons!r}") from None
    from fhnn.data.dataset import SPLITS

    if split not in SPLITS:
        raise ConfigError(f"--split must be one of {', '.join(SPLITS)}, got {split!r}")
    result = evaluate_fit(run_dir, data, hs, split=split)
    for text in result.notes:
        render.note(text)
    if as_json:
        typer.echo(json.dumps(result.json(), indent=2, allow_nan=False))
        return
    table = Table(title=result.title, title_justify="left", box=box.SIMPLE_HEAD, padding=(0, 0, 0, 1))
    shown = [m for m in METRICS.values() if m.header]
    table.add_column("H \\[s]", justify="right")
    for metric in shown:
        table.add_column(metric.header, justify="right")
    for h, row in result.rows.items():
        table.add_row(h, *(metric.format.format(row[metric.name]) for metric in shown))
    render.stdout.print(table)


@app.command()
def predict(
    run_dir: Annotated[
        Path,
        typer.Argument(
            help="Run folder (or ensemble folder) written by `fhnn train` (a vector-field model)."
        ),
    ],
    duration: Annotated[float, typer.Option("--duration", help="Forecast length in seconds.")],
    initial: Annotated[
        str | None,
        typer.Option("--initial", help="Start state x,y,vx,vy [m, m, m/s, m/s] at --t0."),
    ] = None,
    t0: Annotated[
        float,
        typer.Option(
            "--t0",
            help="Time of --initial in seconds on the clock of the run's data (an imported table's "
            "own seconds, or seconds after its first date-time).",
        ),
    ] = 0.0,
    history: Annotated[
        Path | None,
        typer.Option(
            "--history",
            help="Observed tracks (.csv/.parquet as for fhnn import: traj_id, t, x, y[, vx, vy][, Fx, "
            "Fy]): each is forecast from its last sample, its state there fitted to its last "
            "--fit-window seconds.",
        ),
    ] = None,
    forcing: Annotated[
        Path | None,
        typer.Option(
            "--forcing",
            help="Known forces over the forecast (.csv/.parquet: t, Fx, Fy[, traj_id]) [default: none].",
        ),
    ] = None,
    forcing_hold: ForcingHoldOption = "linear",
    dt: Annotated[
        float | None,
        typer.Option("--dt", help="Output step in seconds [default: the history's median step, or 0.05]."),
    ] = None,
    fit_window: Annotated[
        float | None,
        typer.Option(
            "--fit-window", help="Seconds of each history the start state is fitted to [default: 1]."
        ),
    ] = None,
    samples: Annotated[
        int,
        typer.Option(
            "--samples",
            help="Start states drawn from each fitted track's uncertainty and forecast for the band "
            "(with --history; 0: none).",
        ),
    ] = SAMPLES,
    outliers: Annotated[
        str,
        typer.Option(
            "--outliers",
            help="Drop a --history position more than this many noise levels (as the history shows "
            "them) from the cubic through its neighbours before fitting, as fhnn import does; off: keep all.",
        ),
    ] = f"{OUTLIER_SIGMAS:g}",
    output: Annotated[
        Path | None,
        typer.Option(
            "--output", "-o", help="Write the forecast here (.csv or .parquet) [default: CSV on stdout]."
        ),
    ] = None,
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = "s",
) -> None:
    """Forecast with a trained model from a given state or from the end of observed tracks: columns
    traj_id, t, x, y, vx, vy; with a band — from an ensemble (fhnn train --seeds N), from
    --history, or both — then x_lo, x_hi, y_lo, … (5th and 95th percentiles over the members'
    forecasts and those from start states drawn from each fit's uncertainty; x, y, … are the
    members' median), widened where a check on the validation tracks (kept in the run's folder as
    band_check.json) finds that it holds fewer observations than 90 %. A history's start state is
    the one the model explains best (a least squares fit of its trajectory to the last observed
    positions), not a smoother's end point. Times are on the clock of the table the run's data were
    imported from — its seconds, or date-times where it gave date-times — for --t0, the history and
    the forcing alike; the forecast's t is on that
    clock too, as date-times where the history gave date-times."""
    from fhnn.api.predict import predict as predict_fit

    if (initial is None) == (history is None):
        raise ConfigError("give --initial x,y,vx,vy or --history TABLE (one of them)")
    state = None
    if initial is not None:
        try:
            state = [float(v) for v in initial.split(",")]
        except ValueError:
            raise ConfigError(f"--initial expects x,y,vx,vy as four numbers, got {initial!r}") from None
        if len(state) != 4:
            raise ConfigError(f"--initial expects x,y,vx,vy as four numbers, got {initial!r}")
    result = predict_fit(
        run_dir,
        duration,
        initial=state,
        t0=t0,
        history=history,
        forcing=forcing,
        forcing_hold=forcing_hold,
        dt=dt,
        fit_window=fit_window,
        samples=samples,
        outliers=parse_outliers(outliers),
        output=output,
        columns=columns,
        time_unit=time_unit,
    )
    for text in result.notes + result.warnings:
        render.note(text)
    if output is not None:
        render.note(f"wrote {output}")
        return
    for line in result.rows():
        typer.echo(line)
