"""Running one job of the reproduction grid, wherever it runs (a local process or a Ray worker).

A local worker shares the driver's file system: it reads a data set from its path in the
reproduction folder and writes a simulated one there (atomically). A Ray worker may not: it
receives a data set as bytes and returns one as bytes. Either way a model job trains in a private
temporary folder and returns its output as ``{relative path: bytes}``, which the driver writes into
the reproduction folder, so a job that dies leaves nothing behind.

Jobs of one table cell (one model on one data set, seeds apart) may run as one task
(:func:`run_model_jobs`, ``fhnn reproduce --set seeds_together=true``): the members of one ensemble,
their Adam phases as one program; each job's output is still its own.

Model-job output::

    result.json     specification, timings, metrics at every horizon (the specification's averaging under
                    "spec", the paper's under "paper"), per-trajectory divergence, recovery (FHNN),
                    trained_with (members of the group it was trained in, when more than one)
    rollouts.npz    t (T,), pred (K, T, 4): the first K ≤ 4 test rollouts up to 30 s
    run/            the run folder (fhnn.training.run.Run): configuration, weights, history; its
                    data set is recorded as ../../../data/<name>, where the driver keeps it
"""

from __future__ import annotations

import io
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.evaluation.evaluate import evaluate
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.physics.scenarios import get_scenario
from fhnn.runtime import __version__
from fhnn.training.ensemble import train_members
from fhnn.training.run import Run, RunConfig

#: Rollouts kept for the figures: this many test trajectories, up to this time [s].
FIGURE_ROLLOUTS, FIGURE_SECONDS = 4, 30.0


def run_data_job(spec: dict[str, Any], target: str | None = None) -> bytes | str:
    """Simulate the data set of a data job's ``spec``: written to ``target`` (a path the driver
    can read) and that path returned, or, without ``target``, returned as HDF5 bytes."""
    scenario = get_scenario(spec["scenario"])
    config = SimulationConfig.for_scenario(scenario, **spec["settings"])
    dataset = simulate_dataset(scenario, config)
    if target is not None:
        write_dataset(dataset, target)
        return target
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "data.h5"
        write_dataset(dataset, path)
        return path.read_bytes()


def run_model_job(spec: dict[str, Any], data: bytes | str, data_name: str) -> dict[str, bytes]:
    """Train and evaluate the model of a model job's ``spec`` on the data set ``data`` — a path
    (local workers) or HDF5 bytes (Ray workers) — kept by the driver as ``data/<data_name>``;
    returns the job's files."""
    return run_model_jobs([spec], data, data_name)[0]


def run_model_jobs(specs: list[dict[str, Any]], data: bytes | str, data_name: str) -> list[dict[str, bytes]]:
    """:func:`run_model_job` for the jobs ``specs`` of one table cell — one model on one data set,
    seeds apart — trained as the members of one ensemble
    (:func:`~fhnn.training.ensemble.train_members`: their Adam phases as one ``vmap``-ed program,
    each member under its own share of the time budget); returns each job's files, in order. One
    job alone trains as :func:`run_model_job` does; each member's ``train_seconds`` is its share of
    the group's training time (the group's over its size), and ``trained_with`` says how many
    members it was trained with."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = Path(data) if isinstance(data, str) else folder / "data.h5"
        if isinstance(data, bytes):
            path.write_bytes(data)
        dataset = read_dataset(path)
        runs = []
        for j, spec in enumerate(specs):
            config = RunConfig.from_dict(
                {"kind": spec["model"], "model": spec["model_config"], "train": spec["train"]}
            )
            # every member's run folder is kept by the driver as jobs/<id>/run, three levels below data/
            (folder / f"member-{j}").mkdir()
            runs.append(
                Run.create(
                    folder / f"member-{j}" / "run",
                    dataset,
                    config,
                    data_path=path,
                    data_ref=f"../../../data/{data_name}",
                )
            )
        t0 = time.perf_counter()
        if len(runs) == 1:
            runs[0].train(dataset)
        else:
            train_members(runs, dataset, together=True)
        train_seconds = (time.perf_counter() - t0) / len(runs)
        return [
            _job_files(spec, run, dataset, train_seconds, len(runs))
            for spec, run in zip(specs, runs, strict=True)
        ]


def _job_files(
    spec: dict[str, Any], run: Run, dataset: Dataset, train_seconds: float, trained_with: int
) -> dict[str, bytes]:
    """Evaluate a trained job's model; its files (the module docstring's layout)."""
    kind, ablation = spec["model"], spec["ablation"]
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
        "stopped": run.state.stopped,
        "spec_metrics": ev["horizons"],
        "paper_metrics": ev["horizons_other"],
        "diverged": ev["diverged"],
    }
    if trained_with > 1:
        result["trained_with"] = trained_with
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
    for path in sorted(run.folder.iterdir()):
        files[f"run/{path.name}"] = path.read_bytes()
    return files


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
