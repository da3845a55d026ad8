"""Running one job of the reproduction grid, wherever it runs (a local process or a Ray worker).

A job works in a private temporary folder and returns its output as ``{relative path: bytes}``;
the driver writes those files into the reproduction folder. Nothing therefore assumes a file
system shared between the driver and the machine that ran the job, and a job that dies leaves
nothing behind.

Model-job output::

    result.json     specification, timings, metrics at every horizon (SPEC averaging under
                    "spec", the paper's under "paper"), per-trajectory divergence, recovery (FHNN)
    rollouts.npz    t (T,), pred (K, T, 4): the first K ≤ 4 test rollouts up to 30 s
    run/            the run folder (fhnn.training.run.Run): configuration, weights, history
"""

from __future__ import annotations

import io
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from fhnn import __version__
from fhnn.data.dataset import read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.evaluation.evaluate import evaluate
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.physics.scenarios import get_scenario
from fhnn.training.run import MODELS, Run
from fhnn.training.trainer import TrainConfig

#: Rollouts kept for the figures: this many test trajectories, up to this time [s].
FIGURE_ROLLOUTS, FIGURE_SECONDS = 4, 30.0


def run_data_job(spec: dict[str, Any]) -> bytes:
    """Simulate the data set of a data job's ``spec``; returns the HDF5 file's bytes."""
    scenario = get_scenario(spec["scenario"])
    config = SimulationConfig.for_scenario(scenario, **spec["settings"])
    dataset = simulate_dataset(scenario, config)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.h5"
        write_dataset(dataset, path)
        return path.read_bytes()


def run_model_job(spec: dict[str, Any], data: bytes, data_name: str) -> dict[str, bytes]:
    """Train and evaluate the model of a model job's ``spec`` on the data set ``data`` (HDF5
    bytes, stored by the driver as ``data/<data_name>``); returns the job's files."""
    kind, ablation = spec["model"], spec["ablation"]
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "data.h5").write_bytes(data)
        dataset = read_dataset(folder / "data.h5")
        model_config = MODELS[kind].from_dict({"ablation": ablation} if ablation != "none" else {})
        train_config = TrainConfig.from_dict(spec["train"])
        run = Run.create(folder / "run", dataset, f"data/{data_name}", kind, model_config, train_config)
        t0 = time.perf_counter()
        run.train(dataset)
        train_seconds = time.perf_counter() - t0
        model = run.state.best_model
        t0 = time.perf_counter()
        ev = evaluate(model, dataset, spec["horizons"], both_averagings=True, keep_rollout=True)
        eval_seconds = time.perf_counter() - t0
        result: dict[str, Any] = {
            "spec": spec,
            "version": __version__,
            "train_seconds": train_seconds,
            "eval_seconds": eval_seconds,
            "steps": run.state.step,
            "best_val": run.state.best_val,
            "spec_metrics": ev["horizons"],
            "paper_metrics": ev["horizons_other"],
            "diverged": ev["diverged"],
        }
        if kind == "fhnn" and ablation == "none":
            result["recovery"] = {
                "coefficients": coefficient_recovery(model.coefficients, dataset),
                "flow": flow_recovery(model.flow, dataset),
                "actuation": dataset.actuation,
            }
        ro = ev["rollout"]
        keep = ro.t <= FIGURE_SECONDS + 1e-9
        buffer = io.BytesIO()
        np.savez_compressed(buffer, t=ro.t[keep], pred=ro.states[:FIGURE_ROLLOUTS, keep])
        files = {
            "result.json": json.dumps(result, indent=1, default=_json_default).encode(),
            "rollouts.npz": buffer.getvalue(),
        }
        for path in sorted((folder / "run").iterdir()):
            files[f"run/{path.name}"] = path.read_bytes()
        return files


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
