"""fhnn — Floating-Body Hydrodynamic Neural Networks.

Physics-structured system identification of floating bodies: from trajectories of a body drifting
in a 2-D incompressible flow, learn the background flow (as a stream function), the added masses and
the linear and quadratic drag, and predict long horizons stably.

Importing :mod:`fhnn` switches JAX to float64 (a process-global setting, :mod:`fhnn.runtime`):
every computation in this package is carried out in double precision.

The names a Python user needs are available here (imported on first use)::

    import fhnn

    ds = fhnn.simulate("steady_vortex", n_traj=30, duration=5.0)  # or fhnn.read_dataset(path)
    fhnn.write_dataset(ds, "sv.h5")
    config = fhnn.RunConfig().with_settings({"model.width": 32, "train.steps": 2000})
    run = fhnn.train("sv.h5", "runs/sv", config)
    print(fhnn.evaluate(run.best_model, ds, [1, 5])["horizons"])
    run = fhnn.load_run("runs/sv")  # later, from any folder; run.dataset() is its data set
"""

from __future__ import annotations

import importlib
from typing import Any

from fhnn.runtime import __version__

#: Public name → the module that defines it (imported lazily, so ``import fhnn`` stays light).
_PUBLIC = {
    "read_dataset": "fhnn.data.dataset",
    "write_dataset": "fhnn.data.dataset",
    "Dataset": "fhnn.data.dataset",
    "simulate": "fhnn.data.simulate",
    "simulate_dataset": "fhnn.data.simulate",
    "SimulationConfig": "fhnn.data.simulate",
    "read_table": "fhnn.data.table",
    "table_to_dataset": "fhnn.data.table",
    "ImportSettings": "fhnn.data.table",
    "get_scenario": "fhnn.physics.scenarios",
    "SCENARIOS": "fhnn.physics.scenarios",
    "MODELS": "fhnn.models.registry",
    "FHNN": "fhnn.models.fhnn",
    "FHNNConfig": "fhnn.models.fhnn",
    "TrainConfig": "fhnn.training.trainer",
    "RunConfig": "fhnn.training.run",
    "PLANS": "fhnn.training.plans",
    "Run": "fhnn.training.run",
    "train": "fhnn.training.run",
    "load_run": "fhnn.training.run",
    "evaluate": "fhnn.evaluation.evaluate",
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
