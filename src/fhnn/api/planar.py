"""Bodies that turn (3-DOF, docs/spec.md §7), from Python: simulate or import, train, save, load,
evaluate.

::

    from fhnn.api.planar import simulate_turning, train_turning, evaluate_turning

    data = simulate_turning("turning_vortex", seed=3)
    fit = train_turning(data, out="runs/turning")      # model.eqx and run.json in runs/turning
    report = evaluate_turning(fit.model, data)          # forecasts, added masses, damping, flow

A table with a ``heading`` column becomes such a data set with :func:`import_turning` (``fhnn
import`` does the same). The point body's functions (:func:`fhnn.train` and the rest) do not take
a turning body's data.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import equinox as eqx
import jax

from fhnn.data.planar import PlanarDataset, read_planar, simulate_planar, write_planar
from fhnn.data.planar_table import PlanarImportSettings, planar_table_to_dataset, read_planar_table
from fhnn.data.table import parse_columns
from fhnn.errors import DataFormatError
from fhnn.evaluation.planar import evaluate_planar
from fhnn.experiments.planar_figures import forecast_figure
from fhnn.files import atomic_output, check_input_file
from fhnn.models.planar import PlanarFHNN, PlanarModelConfig, build_planar_fhnn, planar_arguments
from fhnn.training.planar import PlanarFit, PlanarTrainConfig, ProgressFn, fit_planar

MODEL_FILE = "model.eqx"
RUN_FILE = "run.json"


def simulate_turning(
    scenario: str = "turning_vortex",
    *,
    seed: int = 0,
    out: str | os.PathLike[str] | None = None,
    **settings: Any,
) -> PlanarDataset:
    """Simulate a turning body's data set (:func:`fhnn.data.planar.simulate_planar`: ``settings``
    are its keyword arguments); written to the HDF5 file ``out`` when given."""
    dataset = simulate_planar(scenario, seed=seed, **settings)
    if out is not None:
        write_planar(dataset, out)
    return dataset


def import_turning(
    table: Any,
    output: str | os.PathLike[str] | None = None,
    *,
    mass: float,
    inertia: float,
    x_g: float = 0.0,
    split: tuple[float, float, float] = (0.7, 0.2, 0.1),
    seed: int = 0,
    time_dependent: bool = False,
    smoother: str = "auto",
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
) -> PlanarDataset:
    """A turning body's data set from a table (:mod:`fhnn.data.planar_table`), as ``fhnn import``
    makes it from a table with a ``heading`` column.

    Args:
        table: a .csv or .parquet path, or a ``pandas.DataFrame``, with columns ``traj_id, t, x,
            y, heading[, Fu, Fv[, Mz] | Fx, Fy]`` [–, s, m, m, rad, N, N, N·m | N, N].
        output: also write the data set here (HDF5).
        mass, inertia, x_g: the body's mass [kg], yaw moment of inertia about the tracked point
            [kg·m²] and centre of gravity ahead of it [m].
        split, seed: fractions of trajectories for train/val/test and the permutation's seed.
        time_dependent, smoother: let the flow change in time; the pose smoother (``"spline"``,
            ``"kalman"``, ``"auto"``).
        columns: the table's names of our columns where they differ (``"t=time,heading=yaw"``).
        time_unit: the unit of numeric times (``"s"``, ``"ms"``, ``"us"``, ``"min"``, ``"h"``).

    Raises:
        ConfigError: a bad setting.
        DataFormatError: a table that is missing, unreadable or inconsistent.
    """
    settings = PlanarImportSettings(
        mass=mass,
        inertia=inertia,
        x_g=x_g,
        split=tuple(float(f) for f in split),
        seed=seed,
        time_dependent=time_dependent,
        smoother=smoother,
    )
    read = read_planar_table(table, columns=parse_columns(columns), time_unit=time_unit)
    dataset = planar_table_to_dataset(read, settings)
    if output is not None:
        write_planar(dataset, output)
    return dataset


def _dataset(data: PlanarDataset | str | os.PathLike[str]) -> PlanarDataset:
    return data if isinstance(data, PlanarDataset) else read_planar(data)


def train_turning(
    data: PlanarDataset | str | os.PathLike[str],
    *,
    model: PlanarModelConfig | None = None,
    training: PlanarTrainConfig | None = None,
    out: str | os.PathLike[str] | None = None,
    progress: ProgressFn | None = None,
) -> PlanarFit:
    """Train a :class:`~fhnn.models.planar.PlanarFHNN` (:func:`fhnn.training.planar.fit_planar`).

    Args:
        data: a data set or its HDF5 file.
        model, training: the configurations (defaults when ``None``).
        out: a folder to write ``model.eqx`` (the weights) and ``run.json`` (the configurations,
            the data-derived arguments, the validation loss, the history and the seconds) into.
        progress: called as ``progress(phase, step, steps, train_loss)``.

    Raises:
        DataFormatError: ``data`` is not a readable turning body's data set, or ``out`` holds a
            model already.
        ConfigError: a bad setting.
    """
    if out is not None and (Path(out) / MODEL_FILE).exists():
        raise DataFormatError(f"{out} holds a model already; give a new folder")
    dataset = _dataset(data)
    model = model or PlanarModelConfig()
    training = training or PlanarTrainConfig()
    fit = fit_planar(dataset, model, training, progress=progress)
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        with atomic_output(folder / MODEL_FILE) as tmp:
            eqx.tree_serialise_leaves(tmp, fit.model)
        run = {
            "model": model.to_dict(),
            "training": training.to_dict(),
            "arguments": planar_arguments(dataset),
            "data": {"scenario": dataset.scenario, "seed": dataset.seed, "obs_noise": dataset.obs_noise},
            "val_loss": fit.val_loss,
            "seconds": fit.seconds,
            "history": fit.history,
        }
        with atomic_output(folder / RUN_FILE) as tmp:
            tmp.write_text(json.dumps(run, indent=1))
    return fit


def load_turning(folder: str | os.PathLike[str]) -> PlanarFHNN:
    """The model :func:`train_turning` wrote into ``folder``.

    Raises:
        DataFormatError: ``folder`` lacks the files, or they do not fit together.
    """
    folder = Path(folder)
    run_path = check_input_file(folder / RUN_FILE, "a turning model's run.json")
    weights = check_input_file(folder / MODEL_FILE, "a turning model's weights")
    try:
        run = json.loads(run_path.read_text())
        like = build_planar_fhnn(
            PlanarModelConfig.from_dict(run["model"]), **run["arguments"], key=jax.random.PRNGKey(0)
        )
        return eqx.tree_deserialise_leaves(weights, like)
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise DataFormatError(f"{folder}: not a turning model ({err})") from None


def evaluate_turning(
    model: PlanarFHNN | str | os.PathLike[str],
    data: PlanarDataset | str | os.PathLike[str],
    *,
    horizon: float = 5.0,
) -> dict[str, Any]:
    """Forecast errors at ``horizon`` [s], added masses, damping and flow against the data's truth
    (:func:`fhnn.evaluation.planar.evaluate_planar`); ``model`` a model or the folder
    :func:`train_turning` wrote."""
    learned = model if isinstance(model, PlanarFHNN) else load_turning(model)
    return evaluate_planar(learned, _dataset(data), horizon=horizon)


def figure_turning(
    model: PlanarFHNN | str | os.PathLike[str],
    data: PlanarDataset | str | os.PathLike[str],
    path: str | os.PathLike[str],
    *,
    horizon: float = 5.0,
) -> Path:
    """Write a PNG of the first test trajectories, true and forecast to ``horizon`` [s], with the
    body's outline every second (:func:`fhnn.experiments.planar_figures.forecast_figure`);
    returns its path."""
    learned = model if isinstance(model, PlanarFHNN) else load_turning(model)
    return forecast_figure(learned, _dataset(data), path, horizon=horizon)


__all__ = [
    "evaluate_turning",
    "figure_turning",
    "import_turning",
    "load_turning",
    "simulate_turning",
    "train_turning",
]
