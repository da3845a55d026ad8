"""Bodies that turn under logged controls, on disk: what ``fhnn import --controls`` and ``fhnn
turning train|evaluate`` run for such data (the in-memory functions are
:mod:`fhnn.api.planar_controls`).

::

    from fhnn.api.planar_controls_files import import_controlled_file, train_controlled_run
    from fhnn.api.planar_controls_files import evaluate_controlled_run

    import_controlled_file("trials.csv", "trials.h5", ["rudder", "rps"], mass=3352.0, inertia=1.03e4)
    train_controlled_run("trials.h5", "runs/ship")             # model.eqx and run.json
    evaluate_controlled_run("runs/ship", "trials.h5", horizon=60)

A data set under controls is its own kind of file (:mod:`fhnn.data.planar_controls_file`), and a
run trained on one records ``kind = "planar_controls"`` and the controls' names in ``run.json``:
the known-force functions of :mod:`fhnn.api.planar` refuse both rather than take controls for
forces.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.api.planar import MODEL_FILE, RUN_FILE
from fhnn.api.planar_controls import ControlledData, evaluate_controlled, import_controlled, train_controlled
from fhnn.data.planar_controls_file import CONTROLS_KIND, file_kind, read_controlled, write_controlled
from fhnn.errors import DataFormatError
from fhnn.experiments.planar_figures import forecast_figure
from fhnn.files import atomic_output, check_input_file
from fhnn.models.planar import PlanarModelConfig, build_planar_fhnn, planar_arguments
from fhnn.models.planar_actuated import ActuatedPlanarFHNN, ActuatorNet
from fhnn.training.planar import PlanarTrainConfig, ProgressFn
from fhnn.training.planar_actuated import ActuatedFit

PathLike = str | os.PathLike[str]


def import_controlled_file(
    table: Any, output: PathLike, controls: Sequence[str], *, mass: float, inertia: float, **options: Any
) -> ControlledData:
    """:func:`fhnn.api.planar_controls.import_controlled` of ``table``, ``controls``, ``mass``
    and ``inertia`` with its keyword ``options`` (``x_g``, ``split``, ``seed``, ``smoother``,
    ``columns``, ``time_unit``), the data set written to the HDF5 file ``output`` (whole or not
    at all).

    Raises:
        ConfigError: a bad setting.
        DataFormatError: a bad table or controls, or ``output`` cannot be written.
        TypeError: an option :func:`~fhnn.api.planar_controls.import_controlled` does not take.
    """
    data = import_controlled(table, controls, mass=mass, inertia=inertia, **options)
    write_controlled(data.dataset, data.controls, output)
    return data


def is_controlled(data: PathLike) -> bool:
    """Whether the HDF5 file ``data`` holds a data set under controls.

    Raises:
        DataFormatError: ``data`` is missing, a folder or not an HDF5 file.
    """
    return file_kind(data) == CONTROLS_KIND


def read_controlled_data(data: ControlledData | PathLike) -> ControlledData:
    """``data`` itself, or the data set under controls its file holds.

    Raises:
        DataFormatError: not such a file.
    """
    if isinstance(data, ControlledData):
        return data
    return ControlledData(*read_controlled(data))


def train_controlled_run(
    data: ControlledData | PathLike,
    out: PathLike,
    *,
    model: PlanarModelConfig | None = None,
    training: PlanarTrainConfig | None = None,
    progress: ProgressFn | None = None,
) -> ActuatedFit:
    """:func:`fhnn.api.planar_controls.train_controlled`, the model written into the new folder
    ``out``: ``model.eqx`` (the weights) and ``run.json`` (``kind``, the ``controls``, under
    ``actuated`` the configurations and the data-derived arguments, the validation loss, the
    history, the seconds).

    Raises:
        DataFormatError: ``data`` is not a data set under controls, or ``out`` holds a model already.
        ConfigError: a bad setting.
    """
    folder = Path(out)
    if (folder / MODEL_FILE).exists():
        raise DataFormatError(f"{out} holds a model already; give a new folder")
    data = read_controlled_data(data)
    model = model or PlanarModelConfig()
    training = training or PlanarTrainConfig()
    fit = train_controlled(data, model=model, training=training, progress=progress)
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_output(folder / MODEL_FILE) as tmp:
        eqx.tree_serialise_leaves(tmp, fit.model)
    run = {
        "kind": CONTROLS_KIND,
        "controls": list(data.controls),
        # under their own key, so that fhnn.api.planar.load_turning finds no known-force model here
        "actuated": {
            "model": model.to_dict(),
            "training": training.to_dict(),
            "arguments": planar_arguments(data.dataset),
        },
        "data": {"scenario": data.dataset.scenario, "seed": data.dataset.seed},
        "val_loss": fit.val_loss,
        "seconds": fit.seconds,
        "history": fit.history,
    }
    with atomic_output(folder / RUN_FILE) as tmp:
        tmp.write_text(json.dumps(run, indent=1))
    return fit


def _run_record(folder: Path) -> dict[str, Any]:
    path = check_input_file(folder / RUN_FILE, "a turning model's run.json")
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise DataFormatError(f"{path}: not readable ({err})") from None
    if not isinstance(record, dict):
        raise DataFormatError(f"{path}: not a run record")
    return record


def is_controlled_run(folder: PathLike) -> bool:
    """Whether the run folder ``folder`` holds a model trained on a data set under controls.

    Raises:
        DataFormatError: ``folder`` has no readable ``run.json``.
    """
    return _run_record(Path(folder)).get("kind") == CONTROLS_KIND


def load_controlled(folder: PathLike) -> tuple[ActuatedPlanarFHNN, tuple[str, ...]]:
    """The model :func:`train_controlled_run` wrote into ``folder`` and its controls' names.

    Raises:
        DataFormatError: ``folder`` lacks the files, holds a known-force model, or they do not
            fit together.
    """
    folder = Path(folder)
    run = _run_record(folder)
    if run.get("kind") != CONTROLS_KIND:
        raise DataFormatError(f"{folder}: a model of known forces, not of controls")
    weights = check_input_file(folder / MODEL_FILE, "a turning model's weights")
    try:
        stored = run["actuated"]
        config = PlanarModelConfig.from_dict(stored["model"])
        controls = tuple(run["controls"])
        n = len(controls)
        body = build_planar_fhnn(config, **stored["arguments"], key=jax.random.PRNGKey(0))
        mlp = eqx.nn.MLP(3 + n, 3, config.width, config.depth, activation=jnp.tanh, key=jax.random.PRNGKey(1))
        # the shapes the weights are read into; every array is replaced by the stored one
        actuator = ActuatorNet(mlp, jnp.ones(3), jnp.zeros(n), jnp.ones(n), jnp.ones(3))
        like = ActuatedPlanarFHNN(body=body, actuator=actuator, n_controls=n)
        return eqx.tree_deserialise_leaves(weights, like), controls
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise DataFormatError(f"{folder}: not a model of controls ({err})") from None


def _model_and_data(
    run: ActuatedPlanarFHNN | PathLike, data: ControlledData | PathLike
) -> tuple[ActuatedPlanarFHNN, ControlledData]:
    data = read_controlled_data(data)
    if isinstance(run, ActuatedPlanarFHNN):
        return run, data
    model, controls = load_controlled(run)
    if controls != data.controls:
        raise DataFormatError(
            f"{run} was trained on controls {', '.join(controls)}; the data hold {', '.join(data.controls)}"
        )
    return model, data


def evaluate_controlled_run(
    run: ActuatedPlanarFHNN | PathLike, data: ControlledData | PathLike, *, horizon: float = 5.0
) -> dict[str, Any]:
    """Forecasts of ``data``'s test trajectories under their logged controls to ``horizon`` [s]
    (:func:`fhnn.api.planar_controls.evaluate_controlled`) and the learned added masses (fit
    parameters: the data fix no force).

    Returns:
        ``{"horizon", "controls", "forecast": {"rmse_pos" [m], "rmse_heading" [rad],
        "diverged"}, "added_mass": {"m_11", "m_22", "m_66": {"learned"}}}``.

    Raises:
        DataFormatError: ``run`` or ``data`` is not of controls, or their controls differ.
        ConfigError: ``horizon`` is not a whole number of seconds within every test trajectory.
    """
    model, data = _model_and_data(run, data)
    masses = zip(("m_11", "m_22", "m_66"), model.added_mass().tolist(), strict=True)
    return {
        "horizon": horizon,
        "controls": list(data.controls),
        "forecast": evaluate_controlled(model, data, horizon=horizon),
        "added_mass": {name: {"learned": value} for name, value in masses},
    }


def figure_controlled_run(
    run: ActuatedPlanarFHNN | PathLike,
    data: ControlledData | PathLike,
    path: PathLike,
    *,
    horizon: float = 5.0,
) -> Path:
    """Write a PNG of the first test trajectories, observed and forecast under their logged
    controls to ``horizon`` [s], with the body's outline every second
    (:func:`fhnn.experiments.planar_figures.forecast_figure`); returns its path."""
    model, data = _model_and_data(run, data)
    return forecast_figure(model, data.dataset, path, horizon=horizon)


__all__ = [
    "evaluate_controlled_run",
    "figure_controlled_run",
    "import_controlled_file",
    "is_controlled",
    "is_controlled_run",
    "load_controlled",
    "read_controlled_data",
    "train_controlled_run",
]
