"""fhnn — Floating-Body Hydrodynamic Neural Networks.

Physics-structured system identification of floating bodies: from trajectories of a body drifting
in a 2-D incompressible flow, learn the background flow (as a stream function), the added masses and
the linear and quadratic drag, and predict long horizons stably.

Importing :mod:`fhnn` switches JAX to float64 (a process-global setting, :mod:`fhnn.runtime`):
every computation in this package is carried out in double precision.

Each command of the ``fhnn`` CLI is a function here with the same options (:mod:`fhnn.api`)::

    import fhnn

    data = fhnn.from_table(df, mass=10.0, area=0.02)  # a pandas DataFrame: traj_id, t, x, y[, Fx, Fy]
    fit = fhnn.train(data, "runs/a", seeds=3)         # or fhnn.load("runs/a") later
    fit.coefficients()                                # pandas.DataFrame, with 90 % intervals
    fit.flow()                                        # xarray.Dataset
    fit.predict(5.0, history=df)                      # a forecast with its band
"""

from __future__ import annotations

import importlib
from typing import Any

from fhnn.runtime import __version__

#: Public name → the module that defines it (imported lazily, so ``import fhnn`` stays light).
_PUBLIC = {
    # one function per command (fhnn.api)
    "simulate": "fhnn.api.data",
    "import_table": "fhnn.api.data",
    "from_table": "fhnn.api.data",
    "info": "fhnn.api.describe",
    "train": "fhnn.api.train",
    "evaluate": "fhnn.api.evaluate",
    "inspect": "fhnn.api.inspect",
    "predict": "fhnn.api.predict",
    "reproduce": "fhnn.api.reproduce",
    "load": "fhnn.api.fit",
    "Fit": "fhnn.api.fit",
    # one function per ``fhnn turning`` command (a body that turns, 3-DOF)
    "simulate_turning": "fhnn.api.planar",
    "import_turning": "fhnn.api.planar",
    "train_turning": "fhnn.api.planar",
    "load_turning": "fhnn.api.planar",
    "evaluate_turning": "fhnn.api.planar",
    "inspect_turning": "fhnn.api.planar_inspect",
    "forecast_turning": "fhnn.api.planar_forecast",
    "train_turning_ensemble": "fhnn.api.planar_ensemble",
    "inspect_turning_ensemble": "fhnn.api.planar_ensemble",
    "evaluate_turning_ensemble": "fhnn.api.planar_ensemble",
    # forecasts from the smoothed last state alone (forecast_turning's fit_window=0)
    "predict_turning": "fhnn.api.planar_predict",
    "predict_turning_ensemble": "fhnn.api.planar_ensemble",
    "import_controlled": "fhnn.api.planar_controls",
    "train_controlled": "fhnn.api.planar_controls",
    # data sets, tables, scenarios
    "read_dataset": "fhnn.data.dataset",
    "write_dataset": "fhnn.data.dataset",
    "Dataset": "fhnn.data.dataset",
    "simulate_dataset": "fhnn.data.simulate",
    "SimulationConfig": "fhnn.data.simulate",
    "read_table": "fhnn.data.table",
    "table_to_dataset": "fhnn.data.conversion",
    "ImportSettings": "fhnn.data.conversion",
    "get_scenario": "fhnn.physics.scenarios",
    "SCENARIOS": "fhnn.physics.scenarios",
    # models, configuration, runs
    "MODELS": "fhnn.models.registry",
    "FHNN": "fhnn.models.fhnn",
    "FHNNConfig": "fhnn.models.fhnn",
    "TrainConfig": "fhnn.training.train_config",
    "RunConfig": "fhnn.training.run",
    "PLANS": "fhnn.training.plans",
    "Run": "fhnn.training.run",
    "load_run": "fhnn.training.run",
    "coefficient_recovery": "fhnn.evaluation.recovery",
    "flow_recovery": "fhnn.evaluation.recovery",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fhnn' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
