"""``fhnn turning simulate|train|evaluate|inspect|predict``: a body that turns (3-DOF), over
:mod:`fhnn.api.planar` and its neighbours."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from fhnn.api.defaults import FIT_WINDOW
from fhnn.cli import render
from fhnn.cli.options import ColumnsOption, QuietOption, TimeUnitOption, app
from fhnn.data.planar import read_planar
from fhnn.errors import ConfigError
from fhnn.models.planar import PlanarModelConfig
from fhnn.physics.planar_scenarios import PLANAR_SCENARIOS
from fhnn.training.planar import PlanarTrainConfig

turning = typer.Typer(
    help="Bodies that turn (3-DOF: surge, sway, yaw): simulate, train, evaluate, inspect, predict.",
    no_args_is_help=True,
    rich_markup_mode=None,
)
app.add_typer(turning, name="turning")


@turning.command()
def simulate(
    scenario: Annotated[str, typer.Argument(help=f"Scenario: {', '.join(PLANAR_SCENARIOS)}.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="HDF5 file to write.")],
    n_traj: Annotated[int, typer.Option(help="Trajectories over all splits (70/20/10 %).")] = 100,
    duration: Annotated[float, typer.Option(help="Train/val trajectory length in s.")] = 20.0,
    test_duration: Annotated[float, typer.Option(help="Test trajectory length in s.")] = 20.0,
    dt: Annotated[float, typer.Option(help="Sampling interval in s.")] = 0.05,
    obs_noise: Annotated[float, typer.Option(help="Std of the noise on every stored state entry.")] = 0.0,
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    quiet: QuietOption = False,
) -> None:
    """Simulate a turning body's data set (train/val/test splits) and write it as HDF5."""
    from fhnn.api.planar import simulate_turning

    data = simulate_turning(
        scenario,
        seed=seed,
        out=output,
        n_traj=n_traj,
        duration=duration,
        test_duration=test_duration,
        dt=dt,
        obs_noise=obs_noise,
    )
    if not quiet:
        sizes = ", ".join(f"{k} {s.states.shape[0]}×{s.states.shape[1]}" for k, s in data.splits.items())
        render.note(f"wrote {output}: {scenario}, seed {seed}; trajectories × samples: {sizes}")


@turning.command()
def train(
    data: Annotated[Path, typer.Argument(help="Data set from `fhnn turning simulate` or `fhnn import`.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="Run folder to write (new).")],
    adam_steps: Annotated[int | None, typer.Option(help="Adam steps [default: 4000].")] = None,
    lbfgs_steps: Annotated[int | None, typer.Option(help="L-BFGS iterations [default: 1000].")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the weights (an ensemble's first member's).")] = 0,
    seeds: Annotated[
        int,
        typer.Option(
            help="Members of an ensemble (seeds SEED, SEED+1, ...), each on its own bootstrap of the "
            "training tracks; 1: a single run."
        ),
    ] = 1,
    damping: Annotated[
        str, typer.Option(help="Damping: diagonal (one per axis) or full (axes coupled, still dissipative).")
    ] = "diagonal",
    quiet: QuietOption = False,
) -> None:
    """Train the 3-DOF FHNN (flow, added masses, damping) and write model.eqx and run.json (with
    --seeds N: an ensemble, one such run folder per member); on data imported with --controls, also
    the map from the controls to the body's forces."""
    from fhnn.api.planar import train_turning
    from fhnn.api.planar_controls_files import is_controlled, train_controlled_run
    from fhnn.api.planar_ensemble import train_turning_ensemble

    if seeds < 1:
        raise ConfigError(f"--seeds must be at least 1, got {seeds}")
    given = {"adam_steps": adam_steps, "lbfgs_steps": lbfgs_steps, "seed": seed}
    config = PlanarTrainConfig(**{k: v for k, v in given.items() if v is not None})
    model = PlanarModelConfig(damping=damping)

    def progress(phase: str, step: int, steps: int, loss: float) -> None:
        if not quiet and (step % 500 == 0 or step == steps):
            render.note(f"{phase} {step}/{steps}: training loss {loss:.3e}")

    if seeds > 1:
        if is_controlled(data):
            raise ConfigError("--seeds: ensembles are trained on data with known forces, not logged controls")
        fits = train_turning_ensemble(
            data, output, members=seeds, model=model, training=config, progress=progress
        )
        trained = sum(fit is not None for fit in fits)
        render.stdout.print(
            f"wrote {output}: an ensemble of {seeds} members ({trained} trained now, "
            f"{seeds - trained} kept); `fhnn turning inspect` gives their intervals",
            soft_wrap=True,
            highlight=False,
        )
        return
    if is_controlled(data):
        fit = train_controlled_run(data, output, model=model, training=config, progress=progress)
        render.stdout.print(
            f"wrote {output}: validation loss {fit.val_loss:.3e} after {fit.seconds:.0f} s; a map from "
            "the controls to forces learned (the added masses are not fixed by such data)",
            soft_wrap=True,
            highlight=False,
        )
        return
    fit = train_turning(data, model=model, training=config, out=output, progress=progress)
    masses = fit.model.added_mass()
    render.stdout.print(
        f"wrote {output}: validation loss {fit.val_loss:.3e} after {fit.seconds:.0f} s; added masses "
        f"m_11 {float(masses[0]):.4g} kg, m_22 {float(masses[1]):.4g} kg, m_66 {float(masses[2]):.4g} kg·m²",
        soft_wrap=True,
        highlight=False,
    )


@turning.command()
def evaluate(
    run: Annotated[Path, typer.Argument(help="Run folder written by `fhnn turning train`.")],
    data: Annotated[
        Path,
        typer.Argument(help="Data set: simulated (scored against its truth) or imported (its observations)."),
    ],
    horizon: Annotated[float, typer.Option(help="Forecast horizon in whole seconds.")] = 5.0,
    as_json: Annotated[bool, typer.Option("--json", help="Print the whole report as JSON.")] = False,
    figure: Annotated[
        Path | None,
        typer.Option(help="Also draw test forecasts, with the body's outline each second, to this PNG."),
    ] = None,
) -> None:
    """Forecast errors and added masses; for a simulation also damping and flow against its truth."""
    from fhnn.api.planar import evaluate_turning, figure_turning
    from fhnn.api.planar_controls_files import (
        evaluate_controlled_run,
        figure_controlled_run,
        is_controlled_run,
    )
    from fhnn.api.planar_ensemble import is_turning_ensemble

    if horizon <= 0:
        raise ConfigError(f"--horizon must be positive, got {horizon:g}")
    if is_turning_ensemble(run):
        _evaluate_ensemble(run, data, horizon, as_json, figure)
        return
    controlled = is_controlled_run(run)
    evaluate, draw = (
        (evaluate_controlled_run, figure_controlled_run) if controlled else (evaluate_turning, figure_turning)
    )
    report = evaluate(run, data, horizon=horizon)
    if figure is not None:
        draw(run, data, figure, horizon=horizon)
    if as_json:
        render.stdout.print_json(json.dumps(report))
        return
    f = report["forecast"]
    lines = [
        f"forecast at {horizon:g} s: RMSE(pos) {f['rmse_pos']:.3g} m, "
        f"RMSE(heading) {f['rmse_heading']:.3g} rad"
        + (f", {f['diverged']} diverged" if f["diverged"] else ""),
        "added masses: "
        + ", ".join(
            f"{k} {v['learned']:.4g}"
            + (f" (true {v['true']:.4g}, {100 * v['rel_error']:.2g} %)" if "true" in v else "")
            for k, v in report["added_mass"].items()
        )
        + (" (fit parameters: no force is known)" if controlled else ""),
    ]
    if "damping" in report:
        axes = ("surge", "sway", "yaw")
        lines += [
            "damping, relative L2: "
            + ", ".join(f"{a} {100 * report['damping'][a]['rel_l2']:.2g} %" for a in axes),
            f"flow, relative L2: {100 * report['flow']['rel_l2']:.2g} %",
        ]
    for line in lines:
        render.stdout.print(line, soft_wrap=True, highlight=False, markup=False)


@turning.command()
def inspect(
    run: Annotated[Path, typer.Argument(help="Run folder written by `fhnn turning train` (known forces).")],
    data: Annotated[Path, typer.Argument(help="The data set it was trained on.")],
    out: Annotated[
        Path | None, typer.Option("--out", help="Folder for the files [default: the run folder].")
    ] = None,
    max_points: Annotated[int, typer.Option(help="At most this many covered relative velocities.")] = 2000,
) -> None:
    """Added masses and damping over the relative velocities the training data cover: prints them
    (beside the truth for a simulation) and writes coefficients.csv, damping.csv and damping.png;
    for an ensemble, the members' median and 90 % interval."""
    from fhnn.api.planar_ensemble import is_turning_ensemble
    from fhnn.api.planar_inspect import inspect_turning

    if is_turning_ensemble(run):
        _inspect_ensemble(run, data, out, max_points)
        return
    found = inspect_turning(run, data, out=out, max_points=max_points)
    table = Table()
    for column in ("quantity", "learned", "unit", "true", "error"):
        table.add_column(column, justify="left" if column in ("quantity", "unit") else "right")
    for row in found.coefficients.to_dict("records"):
        learned = (
            f"{row['value']:.4g}" if _given(row.get("value")) else f"{row['low']:.3g} to {row['high']:.3g}"
        )
        name = row["name"] if _given(row.get("value")) else f"{row['name']} over {row['over']}"
        true = f"{row['true']:.4g}" if _given(row.get("true")) else ""
        error = f"{100 * row['rel_error']:.2g} %" if _given(row.get("rel_error")) else ""
        table.add_row(name, learned, row["unit"], true, error)
    render.stdout.print(table)
    render.note(f"wrote {', '.join(str(p) for p in found.files)}")


@turning.command()
def predict(
    run: Annotated[Path, typer.Argument(help="Run folder written by `fhnn turning train`.")],
    history: Annotated[
        Path,
        typer.Option(
            "--history",
            help="Observed tracks (.csv/.parquet): traj_id, t, x, y, heading and the run's forcing "
            "columns (Fu, Fv[, Mz] or Fx, Fy; a run of controls: its control columns).",
        ),
    ],
    duration: Annotated[float, typer.Option(help="Forecast length in s after each track's last sample.")],
    output: Annotated[
        Path, typer.Option("--output", "-o", help="Forecast table to write (.csv or .parquet).")
    ],
    dt: Annotated[
        float | None, typer.Option(help="Output step in s [default: the history's median step].")
    ] = None,
    fit_window: Annotated[
        float,
        typer.Option(
            "--fit-window",
            help="Seconds before each track's last sample whose observed poses the start state is "
            "fitted to (at least the last 3 samples); 0: start from the smoothed estimate.",
        ),
    ] = FIT_WINDOW,
    smoother: Annotated[str, typer.Option(help="As for `fhnn import`: spline, kalman or auto.")] = "auto",
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = "s",
    quiet: QuietOption = False,
) -> None:
    """Continue each observed track from the state the model fits to its last --fit-window
    seconds (started from the pose and body-frame velocity smoothed as `fhnn import` does), its
    last forces or controls held; write traj_id, t, x, y, heading, u, v, r (an ensemble: the
    members' median, each with _lo and _hi, a 90 % interval)."""
    from fhnn.api.planar_forecast import forecast_turning

    forecast = forecast_turning(
        run,
        history,
        duration,
        fit_window=fit_window,
        dt=dt,
        smoother=smoother,
        columns=columns,
        time_unit=time_unit,
        output=output,
    )
    if not quiet:
        tracks = forecast["traj_id"].nunique()
        render.note(f"wrote {output}: {tracks} tracks continued {duration:g} s, {len(forecast)} rows")


def _evaluate_ensemble(run: Path, data: Path, horizon: float, as_json: bool, figure: Path | None) -> None:
    """``turning evaluate`` of an ensemble: each member's forecast errors and masses."""
    from fhnn.api.planar_ensemble import evaluate_turning_ensemble

    if figure is not None:
        raise ConfigError(f"--figure draws one run: give a member, e.g. {run / 'seed-0'}")
    reports = evaluate_turning_ensemble(run, data, horizon=horizon)
    if as_json:
        render.stdout.print_json(json.dumps(reports))
        return
    for report in reports:
        f, masses = report["forecast"], report["added_mass"]
        render.stdout.print(
            f"{report['member']}: forecast at {horizon:g} s RMSE(pos) {f['rmse_pos']:.3g} m, "
            f"RMSE(heading) {f['rmse_heading']:.3g} rad; added masses "
            + ", ".join(f"{k} {v['learned']:.4g}" for k, v in masses.items()),
            soft_wrap=True,
            highlight=False,
            markup=False,
        )


def _inspect_ensemble(run: Path, data: Path, out: Path | None, max_points: int) -> None:
    """``turning inspect`` of an ensemble: the members' median and interval per quantity."""
    from fhnn.api.planar_ensemble import inspect_turning_ensemble

    dataset = read_planar(data)  # once: for the intervals and for its noise level
    found = inspect_turning_ensemble(run, dataset, out=out, max_points=max_points)
    rows = found.coefficients.to_dict("records")
    table = Table(title=f"{found.members} members: median and 90 % interval")
    for column in ("quantity", "median", "90 % interval", "unit", "true", "error", "holds"):
        table.add_column(column, justify="left" if column in ("quantity", "unit") else "right")
    for row in rows:
        truth = _given(row.get("true"))
        table.add_row(
            row["name"],
            f"{row['value']:.4g}",
            f"{row['lo']:.4g} to {row['hi']:.4g}",
            row["unit"],
            f"{row['true']:.4g}" if truth else "",
            f"{100 * row['rel_error']:.2g} %" if truth else "",
            ("yes" if row["inside"] else "no") if truth else "",
        )
    render.stdout.print(table)
    over = [row["over"] for row in rows if isinstance(row.get("over"), str)]
    render.stdout.print(
        "damping: X_d/u_r is the least-squares ratio of the surge damping to u_r (and so for sway and "
        f"yaw) over the covered relative velocities: {', '.join(over)}",
        soft_wrap=True,
        highlight=False,
        markup=False,
    )
    noise = dataset.obs_noise
    if noise > 0:
        render.note(
            f"the data are noisy (noise level {noise:.3g}): the intervals hold the members' spread, not "
            "the bias that noise gives the fit; on simulated noisy data some missed the truth, most "
            "with noise on every state entry, fewer from an imported table of noisy poses (the "
            "documentation's Benchmarks page)"
        )
    render.note(f"wrote {', '.join(str(p) for p in found.files)}")


def _given(value: object) -> bool:
    """Whether a table cell holds a number (pandas fills a missing one with NaN)."""
    return isinstance(value, int | float) and value == value
