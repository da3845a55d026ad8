"""``fhnn simulate``, ``fhnn import``, ``fhnn info`` and ``fhnn scenarios``."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from fhnn.cli import render
from fhnn.cli.options import ColumnsOption, ForcingHoldOption, TimeUnitOption, app
from fhnn.data.cleaning import GAP_STEPS, OUTLIER_SIGMAS
from fhnn.data.conversion import parse_split
from fhnn.data.derivatives import AUTO_SPLINE_ROWS
from fhnn.data.planar import PlanarDataset
from fhnn.data.planar_table import has_heading
from fhnn.data.table import parse_columns
from fhnn.errors import ConfigError
from fhnn.physics.scenarios import SCENARIOS, UNITS
from fhnn.training.settings import parse_params


@app.command()
def simulate(
    scenario: Annotated[str, typer.Argument(help=f"Scenario: {', '.join(SCENARIOS)}.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="HDF5 file to write.")],
    n_traj: Annotated[
        int | None, typer.Option(help="Trajectories over all splits [default: the scenario's]")
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option(help="Train/val trajectory length in s [default: the scenario's]"),
    ] = None,
    test_duration: Annotated[
        float | None, typer.Option(help="Test trajectory length in s [default: the scenario's]")
    ] = None,
    dt: Annotated[float | None, typer.Option(help="Sampling interval in s [default: the scenario's]")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    actuation: Annotated[
        str | None, typer.Option(help="none|random (sinusoidal forcing) [default: the scenario's]")
    ] = None,
    obs_noise: Annotated[
        float | None,
        typer.Option(help="Std of observation noise on stored states [default: the scenario's]"),
    ] = None,
    param: Annotated[
        list[str] | None,
        typer.Option(
            "--param",
            "-p",
            help="Scenario parameter NAME=VALUE (repeatable); see `fhnn scenarios`.",
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar or summary.")] = False,
) -> None:
    """Simulate a ground-truth data set (train/val/test splits) and write it as HDF5."""
    from fhnn.api.data import info as data_info
    from fhnn.api.data import simulate as simulate_data

    dataset = simulate_data(
        scenario,
        output,
        params=parse_params(param or [], "--param"),
        progress=not quiet,
        n_traj=n_traj,
        duration=duration,
        test_duration=test_duration,
        dt=dt,
        seed=seed,
        actuation=actuation,
        obs_noise=obs_noise,
    )
    if not quiet:
        render.summary(data_info(dataset), str(output))


@app.command("import")
def import_table(
    table: Annotated[
        Path,
        typer.Argument(
            help="Table of samples (.csv or .parquet): traj_id, t, x, y[, vx, vy][, Fx, Fy] in SI "
            "units; t in seconds or as ISO-8601 date-times; a CSV separated by commas, semicolons or tabs. "
            "With a heading column (rad, counter-clockwise from x): a body that turns, with columns "
            "traj_id, t, x, y, heading[, Fu, Fv[, Mz] (body frame) | Fx, Fy (world frame)]."
        ),
    ],
    output: Annotated[Path, typer.Option("--output", "-o", help="HDF5 data set to write.")],
    mass: Annotated[float, typer.Option("--mass", help="The body's dry mass M in kg.")],
    area: Annotated[
        float | None, typer.Option("--area", help="The body's reference area A in m² (a point body).")
    ] = None,
    inertia: Annotated[
        float | None,
        typer.Option("--inertia", help="Yaw moment of inertia about the tracked point in kg·m² (heading)."),
    ] = None,
    x_g: Annotated[
        float, typer.Option("--x-g", help="Centre of gravity ahead of the tracked point in m (heading).")
    ] = 0.0,
    rho: Annotated[float, typer.Option("--rho", help="Fluid density in kg/m³.")] = 1000.0,
    volume: Annotated[
        float | None, typer.Option("--volume", help="Displaced volume V in m³ [default: M / rho]")
    ] = None,
    split: Annotated[
        str,
        typer.Option(
            "--split", help="Percent of trajectories for train/val/test, each > 0 (each gets at least one)."
        ),
    ] = "70/20/10",
    seed: Annotated[int, typer.Option(help="Seed of the split's permutation.")] = 0,
    time_dependent: Annotated[
        bool, typer.Option("--time-dependent", help="Let models learn a flow that changes in time.")
    ] = False,
    smoother: Annotated[
        str,
        typer.Option(
            "--smoother",
            help="Velocity estimator where the table has none: spline (trains the better model), "
            "kalman (an RTS smoother, ~10x faster on large tables), or auto: the spline up to "
            f"{AUTO_SPLINE_ROWS:,} rows, kalman above.",
        ),
    ] = "auto",
    max_gap: Annotated[
        str,
        typer.Option(
            "--max-gap",
            help="Split a trajectory into pieces where two samples are more than this many seconds "
            f"apart (inf: never); auto: more than {GAP_STEPS:g}x its median step. Pieces keep the "
            "trajectory's split and are named ID#1, ID#2, ...; pieces under 3 samples are dropped "
            "and counted.",
        ),
    ] = "auto",
    outliers: Annotated[
        str,
        typer.Option(
            "--outliers",
            help="Drop a position more than this many noise levels from the cubic through its two "
            "neighbours either side (a tracker's glitch; one among a track's first or last two samples "
            "shows in its neighbours' residuals only, so it must be larger to be seen), counted in the "
            "summary; off: keep every sample.",
        ),
    ] = f"{OUTLIER_SIGMAS:g}",
    columns: ColumnsOption = None,
    time_unit: TimeUnitOption = "s",
    forcing: Annotated[
        Path | None,
        typer.Option(
            "--forcing",
            help="Known forces as a separate table (.csv/.parquet: t, Fx, Fy[, traj_id]) on the "
            "table's clock, e.g. each time a thruster switches (the table then has no Fx, Fy).",
        ),
    ] = None,
    forcing_hold: ForcingHoldOption = "linear",
    controls: Annotated[
        str | None,
        typer.Option(
            "--controls",
            help="With a heading column: the table's control columns (1 to 3, comma-separated, e.g. "
            "rudder,rps) in place of known forces; `fhnn turning train` then learns the map from "
            "controls to forces.",
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No summary.")] = False,
) -> None:
    """Import observed trajectories from a table into a data set: rows in any order, irregular times,
    unequal lengths; rows with missing values are dropped and counted; a trajectory with a long gap
    (--max-gap) becomes pieces; glitches (--outliers) are dropped and counted; velocities the table
    lacks are estimated from the positions (a smoother held to the noise level they show).
    Trajectories are split into train/val/test by a seeded permutation. A table with a heading
    column makes a turning body's data set (--mass, --inertia; train it with `fhnn turning train`),
    driven by known forces or by the --controls columns."""
    from fhnn.api.data import import_table as import_data
    from fhnn.api.data import info as data_info
    from fhnn.api.planar import import_turning
    from fhnn.api.planar_controls_files import import_controlled_file

    if has_heading(table, parse_columns(columns)):
        if area is not None or forcing is not None:
            raise ConfigError("--area and --forcing apply to a table without a heading column (a point body)")
        if inertia is None:
            raise ConfigError("--inertia is needed for a table with a heading column (a body that turns)")
        if controls is not None:
            if time_dependent:
                raise ConfigError("--time-dependent does not apply with --controls")
            names = [c.strip() for c in controls.split(",")]
            controlled = import_controlled_file(
                table,
                output,
                names,
                mass=mass,
                inertia=inertia,
                x_g=x_g,
                split=parse_split(split),
                seed=seed,
                smoother=smoother,
                columns=columns,
                time_unit=time_unit,
            )
            if not quiet:
                _turning_summary(controlled.dataset, output, f"controls {', '.join(controlled.controls)}")
            return
        data = import_turning(
            table,
            output,
            mass=mass,
            inertia=inertia,
            x_g=x_g,
            split=parse_split(split),
            seed=seed,
            time_dependent=time_dependent,
            smoother=smoother,
            columns=columns,
            time_unit=time_unit,
        )
        if not quiet:
            _turning_summary(data, output)
        return
    if controls is not None:
        raise ConfigError("--controls applies to a table with a heading column (a body that turns)")
    if area is None:
        raise ConfigError("--area is needed for a table without a heading column (a point body)")
    if inertia is not None:
        raise ConfigError("--inertia applies to a table with a heading column; this one has none")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dataset = import_data(
            table,
            output,
            mass=mass,
            area=area,
            rho=rho,
            volume=volume,
            split=split,
            seed=seed,
            time_dependent=time_dependent,
            smoother=smoother,
            max_gap=max_gap,
            outliers=outliers,
            columns=columns,
            time_unit=time_unit,
            forcing=forcing,
            forcing_hold=forcing_hold,
        )
    for warning in caught:
        render.note(f"warning: {warning.message}")
    if not quiet:
        render.summary(data_info(dataset), str(output))


def _turning_summary(data: PlanarDataset, output: Path, forcing: str = "") -> None:
    """One line on an imported turning body's data set (``forcing``: what drives it, if said)."""
    sizes = ", ".join(f"{k} {s.states.shape[0]}" for k, s in data.splits.items())
    noise = data.params["noise"]
    under = f" under {forcing}" if forcing else ""
    render.note(
        f"wrote {output}: a turning body's data set{under}; trajectories {sizes}; "
        f"{data.params['rows']} rows, "
        f"{data.params['dropped']} dropped; noise: position {noise['position']:.3g} m, heading "
        f"{noise['heading']:.3g} rad; smoother {data.params['smoother']}"
    )


def _turning_info(info: dict, path: Path) -> None:
    """A turning body's data set (:func:`fhnn.api.planar_info.turning_info`) in a few lines."""
    forcing = f"controls {', '.join(info['controls'])}" if info["controls"] else "known forces"
    lines = [
        f"{path}: a turning body's data set under {forcing}; scenario {info['scenario']}, "
        f"seed {info['seed']}",
        f"body: mass {info['mass']:.4g} kg, inertia {info['inertia']:.4g} kg·m², x_g {info['x_g']:.4g} m",
        "trajectories × samples (longest): "
        + ", ".join(
            f"{k} {v['trajectories']} × {v['samples']} ({v['duration']:.3g} s)"
            for k, v in info["splits"].items()
        ),
        "training states cover: "
        + ", ".join(f"{k} {lo:.3g} to {hi:.3g}" for k, (lo, hi) in info["covered"].items()),
    ]
    if info.get("noise"):
        noise = info["noise"]
        lines.append(
            f"noise seen: position {noise['position']:.3g} m, heading {noise['heading']:.3g} rad; "
            f"smoother {info['smoother']}"
        )
    for line in lines:
        render.stdout.print(line, soft_wrap=True, highlight=False, markup=False)


@app.command()
def info(
    file: Annotated[Path, typer.Argument(help="An fhnn HDF5 data set.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
) -> None:
    """Describe a data set: scenario, parameters, split sizes, and the ranges of r, speed and σ
    covered; for a turning body's, the body, the split sizes and the ranges of its states."""
    import json

    from fhnn.api.describe import info as describe
    from fhnn.api.describe import is_turning

    described = describe(file)
    if as_json:
        typer.echo(json.dumps(described, indent=2, sort_keys=True))
    elif is_turning(file):
        _turning_info(described, file)
    else:
        render.summary(described, str(file))


@app.command()
def scenarios() -> None:
    """List the scenarios: their parameters with units and defaults, and default data-set sizes."""
    for name, cls in SCENARIOS.items():
        d = cls.defaults
        sizes = (
            f"{d.n_traj} trajectories split {'/'.join(f'{100 * f:g}' for f in d.split)} %, train/val "
            f"{d.duration:g} s, test {d.test_duration:g} s, dt {d.dt:g} s, actuation {d.actuation}"
            + (f", observation noise {d.obs_noise:g}" if d.obs_noise else "")
        )
        render.stdout.print(f"\n[bold]{name}[/bold] — {cls.summary}", soft_wrap=True)
        render.stdout.print(f"default data set: {sizes}", soft_wrap=True, highlight=False)
        table = Table()
        table.add_column("parameter")
        table.add_column("default", justify="right")
        table.add_column("unit")
        for key, value in cls().to_dict().items():
            table.add_row(key, str(value), UNITS.get(key, ""))
        render.stdout.print(table)
