"""Bodies that turn under logged controls, from Python: import a table whose forcing is control
columns (rudder angle, propeller speed, …), train a model with a learned actuator map, forecast.

::

    from fhnn.api.planar_controls import import_controlled, train_controlled, evaluate_controlled

    data = import_controlled("trials.csv", ["rudder", "rps"], mass=3352.0, inertia=1.03e4)
    fit = train_controlled(data)
    errors = evaluate_controlled(fit.model, data, horizon=60)   # held-out forecasts vs observed

The table is a turning body's (:func:`fhnn.api.planar.import_turning`) without force columns; the
model is :class:`~fhnn.models.planar_actuated.ActuatedPlanarFHNN`. Its added masses are not fixed
by such data (no force is known), so no coefficients are reported.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from fhnn.api.planar import import_turning
from fhnn.data.planar import PlanarDataset
from fhnn.data.planar_controls import controls_as_forcing
from fhnn.data.table import parse_columns
from fhnn.evaluation.planar import forecast, forecast_errors
from fhnn.models.planar import PlanarModelConfig
from fhnn.models.planar_actuated import ActuatedPlanarFHNN
from fhnn.training.planar import PlanarTrainConfig, ProgressFn
from fhnn.training.planar_actuated import ActuatedFit, fit_actuated


@dataclasses.dataclass(frozen=True)
class ControlledData:
    """A turning body's data set whose forces channel holds ``controls`` (their column names, in
    slot order)."""

    dataset: PlanarDataset
    controls: tuple[str, ...]


def import_controlled(
    table: Any,
    controls: Sequence[str],
    *,
    mass: float,
    inertia: float,
    x_g: float = 0.0,
    split: tuple[float, float, float] = (0.7, 0.2, 0.1),
    seed: int = 0,
    smoother: str = "auto",
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
) -> ControlledData:
    """A turning body's data set from a table with control columns instead of forces.

    Args:
        table: a .csv or .parquet path, or a ``pandas.DataFrame``, with columns ``traj_id, t, x,
            y, heading`` [–, s, m, m, rad] and the ``controls``.
        controls: one to three control columns' names (any units).
        mass, inertia, x_g: the body's mass [kg], yaw moment of inertia about the tracked point
            [kg·m²] and centre of gravity ahead of it [m].
        split, seed, smoother, time_unit: as :func:`fhnn.api.planar.import_turning`.
        columns: the table's names of the turning body's columns where they differ
            (``"t=time,heading=yaw"``); controls go by their own names.

    Raises:
        ConfigError: a bad setting.
        DataFormatError: a table that is missing, unreadable or inconsistent, or whose controls
            are bad (:func:`fhnn.data.planar_controls.controls_as_forcing`).
    """
    forcing = controls_as_forcing(table, controls, parse_columns(columns))
    dataset = import_turning(
        forcing,
        mass=mass,
        inertia=inertia,
        x_g=x_g,
        split=split,
        seed=seed,
        smoother=smoother,
        time_unit=time_unit,
    )
    return ControlledData(dataset, tuple(controls))


def train_controlled(
    data: ControlledData,
    *,
    model: PlanarModelConfig | None = None,
    training: PlanarTrainConfig | None = None,
    progress: ProgressFn | None = None,
) -> ActuatedFit:
    """Train an :class:`~fhnn.models.planar_actuated.ActuatedPlanarFHNN` on ``data``
    (:func:`fhnn.training.planar_actuated.fit_actuated`; defaults when a configuration is ``None``)."""
    return fit_actuated(data.dataset, len(data.controls), model, training, progress=progress)


def evaluate_controlled(
    model: ActuatedPlanarFHNN, data: ControlledData, *, horizon: float = 60.0
) -> dict[str, float]:
    """Forecasts of ``data``'s test trajectories from each first (estimated) state under their
    logged controls, against their observed pose: ``rmse_pos`` [m] and ``rmse_heading`` [rad] at
    every whole second up to ``horizon`` [s], and the count of ``diverged`` forecasts
    (:func:`fhnn.evaluation.planar.forecast_errors`).

    Raises:
        ConfigError: ``horizon`` is not a whole number of seconds or exceeds a test trajectory.
    """
    test = data.dataset.splits["test"]
    pred, ok = forecast(model, test, horizon)
    return forecast_errors(pred, ok, test, horizon)


__all__ = ["ControlledData", "evaluate_controlled", "import_controlled", "train_controlled"]
