"""Data sets: ``fhnn.simulate``, ``fhnn.import_table`` / ``fhnn.from_table`` and ``fhnn.info``,
as ``fhnn simulate``, ``fhnn import`` and ``fhnn info``."""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn

from fhnn.api.report import Reporter, fault_point, reporter
from fhnn.data.cleaning import OUTLIER_SIGMAS, parse_max_gap, parse_outliers
from fhnn.data.clock import SECONDS_ONLY
from fhnn.data.conversion import ImportSettings, parse_split, table_to_dataset
from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.data.summary import summarize
from fhnn.data.table import parse_columns, read_forcing, read_table
from fhnn.files import check_output_path
from fhnn.physics.scenarios import Scenario, scenario_class


def simulate(
    scenario: str | Scenario,
    output: str | os.PathLike[str] | None = None,
    *,
    params: Mapping[str, Any] | None = None,
    progress: Reporter | bool = False,
    **settings: Any,
) -> Dataset:
    """Simulate a ground-truth data set (train/val/test splits) of a scenario.

    Args:
        scenario: a scenario's name (``fhnn scenarios`` lists them) or a scenario object.
        output: also write the data set here (HDF5).
        params: the scenario's parameters by name (a name's scenario only), e.g. ``{"gamma": 2.0}``.
        progress: progress bars (``True``) on the terminal, or a :class:`~fhnn.api.report.Reporter`.
        settings: :class:`~fhnn.data.simulate.SimulationConfig` fields (``n_traj``, ``duration``,
            ``test_duration``, ``dt`` [s], ``seed``, ``actuation``, ``obs_noise``); ``None`` keeps
            the scenario's default.

    Returns:
        The :class:`~fhnn.data.dataset.Dataset`.

    Raises:
        ConfigError: an unknown scenario, parameter or setting, or a bad value.
        SimulationError: trajectories the simulator could not produce.
    """
    if isinstance(scenario, str):
        sc = scenario_class(scenario).from_dict(dict(params or {}))
    else:
        sc = scenario
    config = SimulationConfig.for_scenario(sc, **settings)
    if output is not None:
        check_output_path(Path(output))
    say = reporter(progress)
    with say.progress(
        TextColumn("simulating {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        transient=False,
    ) as bar:
        tasks: dict[str, Any] = {}

        def step(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = bar.add_task(label, total=total)
            bar.update(tasks[label], completed=done)
            fault_point(label, done)

        dataset = simulate_dataset(sc, config, progress=step)
    if output is not None:
        write_dataset(dataset, output)
    return dataset


def import_table(
    table: Any,
    output: str | os.PathLike[str] | None = None,
    *,
    mass: float,
    area: float,
    rho: float = 1000.0,
    volume: float | None = None,
    split: str | tuple[float, float, float] = "70/20/10",
    seed: int = 0,
    time_dependent: bool = False,
    smoother: str = "auto",
    max_gap: str | float = "auto",
    outliers: str | float | None = OUTLIER_SIGMAS,
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
    forcing: Any = None,
    forcing_hold: str = "linear",
) -> Dataset:
    """A data set from a table of observed trajectories, as ``fhnn import`` makes it.

    Args:
        table: a .csv or .parquet path, or a ``pandas.DataFrame``, with columns ``traj_id, t, x,
            y[, vx, vy][, Fx, Fy]`` [–, s, m, m/s, N]; ``t`` in seconds or ISO-8601 date-times.
        output: also write the data set here (HDF5).
        mass, area, rho, volume: the body's dry mass M [kg], reference area A [m²], the fluid's
            density [kg/m³] and the displaced volume V [m³] (default M / rho).
        split, seed: percent of trajectories for train/val/test (``"70/20/10"``) or fractions,
            and the seed of the split's permutation.
        time_dependent, smoother: let models learn a flow that changes in time; the velocity
            estimator where the table has none (``"spline"``, ``"kalman"``, ``"auto"``).
        max_gap: split a trajectory where samples are more than this many seconds apart
            (``"auto"``: more than 10× its median step; ``"inf"``: never).
        outliers: drop a position this many noise levels off its neighbours' cubic (or ``None``).
        columns: the table's names of our columns where they differ, e.g. ``{"traj_id": "track",
            "t": "time"}`` or ``"traj_id=track,t=time"``.
        time_unit: the unit of numeric times (``"s"``, ``"ms"``, ``"us"``, ``"min"``, ``"h"``).
        forcing, forcing_hold: known forces as a separate table (path or DataFrame, ``t, Fx,
            Fy[, traj_id]`` [s, N] on the table's clock) instead of ``Fx, Fy`` columns, read
            ``"linear"`` (interpolated) or ``"previous"`` (held until the next row; the change
            times are kept for training and evaluation).

    Returns:
        The :class:`~fhnn.data.dataset.Dataset`.

    Raises:
        ConfigError: a bad setting.
        DataFormatError: a table that is missing, unreadable or inconsistent.
    """
    mapping = parse_columns(columns)
    settings = ImportSettings(
        mass=mass,
        area=area,
        rho=rho,
        volume=volume,
        split=parse_split(split) if isinstance(split, str) else tuple(float(f) for f in split),
        seed=seed,
        time_dependent=time_dependent,
        smoother=smoother,
        max_gap=parse_max_gap(str(max_gap)),
        outlier_sigmas=parse_outliers(str(outliers)) if outliers is not None else None,
        forcing_hold=forcing_hold,
    )
    if output is not None:
        check_output_path(Path(output))
    source = Path(table).name if isinstance(table, str | os.PathLike) else "DataFrame"
    read = read_table(table, columns=mapping, time_unit=time_unit)
    forces = None
    if forcing is not None:
        origin = SECONDS_ONLY if read.time_origin is None else read.time_origin
        forces = read_forcing(forcing, origin, mapping, time_unit)
    dataset = table_to_dataset(read, settings, source=source, time_unit=time_unit, forcing=forces)
    for text in dataset.extra["import"]["warnings"]:
        warnings.warn(text, UserWarning, stacklevel=2)
    if output is not None:
        write_dataset(dataset, output)
    return dataset


def from_table(table: Any, **settings: Any) -> Dataset:
    """A data set from a ``pandas.DataFrame`` (or a table's path) in memory:
    :func:`import_table` without a file."""
    return import_table(table, **settings)


def info(data: Dataset | str | os.PathLike[str]) -> dict[str, Any]:
    """What ``fhnn info`` prints: scenario, parameters, split sizes and the ranges covered."""
    return summarize(data if isinstance(data, Dataset) else read_dataset(data))
