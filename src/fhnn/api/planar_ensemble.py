"""Ensembles of turning-body models (``fhnn turning train --seeds N``): members trained on
bootstraps of the training trajectories, and intervals from their spread for the added masses,
the damping and forecasts.

::

    from fhnn.api.planar_ensemble import inspect_turning_ensemble, train_turning_ensemble

    train_turning_ensemble("tracks.h5", "runs/ens", members=3)
    found = inspect_turning_ensemble("runs/ens", "tracks.h5")
    found.coefficients  # name, unit, value (the members' median), lo, hi, ...

The folder is an ensemble folder as :mod:`fhnn.training.ensemble` lays it out (``ensemble.json``
and one run folder ``seed-S`` per member, each what :func:`fhnn.api.planar.train_turning` writes),
its manifest marked ``"body": "turning"``. Member ``S`` trains with weights seeded ``S`` on the
bootstrap :func:`fhnn.training.planar_ensemble.bootstrap_planar` draws from ``S``. Intervals are
:func:`fhnn.training.ensemble.interval`'s: the members' mean ± ``t(0.95; N−1) · s · √(1 + 1/N)``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from fhnn.api.planar import MODEL_FILE, ProgressFn, load_turning, train_turning
from fhnn.api.planar_inspect import write_inspection
from fhnn.api.planar_predict import COLUMNS, predict_turning
from fhnn.data.planar import PlanarDataset, read_planar
from fhnn.data.table import check_table_name, write_table
from fhnn.errors import ConfigError, DataFormatError
from fhnn.evaluation.planar_coefficients import AXES, MASSES, covered_relative_velocities
from fhnn.files import check_output_path, check_writable_folder, write_atomic
from fhnn.models.planar import PlanarFHNN, PlanarModelConfig
from fhnn.training.ensemble import (
    LEVEL,
    MANIFEST,
    interval,
    is_ensemble,
    member_folders,
    start_ensemble,
)
from fhnn.training.planar import PlanarFit, PlanarTrainConfig
from fhnn.training.planar_ensemble import bootstrap_planar

PathLike = str | os.PathLike[str]
#: The manifest's mark of a turning body's ensemble.
BODY = "turning"
#: Per axis: the name of the equivalent linear damping coefficient and its unit.
RATIOS = (("X_d/u_r", "N·s/m"), ("Y_d/v_r", "N·s/m"), ("N_d/r_r", "N·m·s"))


def is_turning_ensemble(folder: PathLike) -> bool:
    """Whether ``folder`` holds an ensemble of turning-body models (its manifest marked so)."""
    if not is_ensemble(folder):
        return False
    try:
        return json.loads((Path(folder) / MANIFEST).read_text()).get("body") == BODY
    except (OSError, ValueError, AttributeError):
        return False


def train_turning_ensemble(
    data: PlanarDataset | PathLike,
    out: PathLike,
    *,
    members: int = 3,
    model: PlanarModelConfig | None = None,
    training: PlanarTrainConfig | None = None,
    progress: ProgressFn | None = None,
) -> list[PlanarFit | None]:
    """Train ``members`` turning-body models into ``out/seed-S``, ``S = training.seed + k``, each
    on its own bootstrap of the training trajectories (:func:`train_turning` on
    :func:`~fhnn.training.planar_ensemble.bootstrap_planar` of ``data``). A member already
    trained (its ``run.json`` written) is kept, so the same call finishes an interrupted ensemble.

    Args:
        data: a turning body's data set or its HDF5 file (known forces).
        out: the ensemble folder (new, or one this function started with the same seeds).
        members: how many members, at least 2.
        model, training: the configurations (defaults when ``None``); ``training.seed`` is the
            first member's seed.
        progress: called as ``progress(phase, step, steps, train_loss)``; ``phase`` is prefixed
            with ``seed-S``.

    Returns:
        Each member's :class:`~fhnn.training.planar.PlanarFit`, ``None`` for one kept from before.

    Raises:
        ConfigError: fewer than 2 members, ``out`` holds a single run, an ensemble of other seeds
            or a point body's ensemble.
        DataFormatError: ``data`` is not a readable turning body's data set, or has fewer than 2
            training trajectories.
    """
    if members < 2:
        raise ConfigError(f"an ensemble needs at least 2 members, got {members}")
    dataset = data if isinstance(data, PlanarDataset) else read_planar(data)
    if dataset.splits["train"].t.shape[0] < 2:
        raise DataFormatError("a bootstrap ensemble needs at least 2 training trajectories")
    model = model or PlanarModelConfig()
    training = training or PlanarTrainConfig()
    folder = Path(out)
    fresh = not is_ensemble(folder)
    seeds = [training.seed + k for k in range(members)]
    folders = start_ensemble(folder, seeds)
    manifest_path = folder / MANIFEST
    manifest = json.loads(manifest_path.read_text())
    if fresh:
        manifest |= {"body": BODY, "bootstrap": True}
        write_atomic(manifest_path, json.dumps(manifest, indent=1))
    elif manifest.get("body") != BODY:
        raise ConfigError(f"{folder} holds a point body's ensemble; train the turning body into a new folder")
    fits: list[PlanarFit | None] = []
    for seed, member in zip(seeds, folders, strict=True):
        if (member / "run.json").is_file():
            fits.append(None)
            continue
        (member / MODEL_FILE).unlink(missing_ok=True)  # weights of a member stopped before its run.json

        def told(phase: str, step: int, steps: int, loss: float, name: str = member.name) -> None:
            if progress is not None:
                progress(f"{name} {phase}", step, steps, loss)

        fits.append(
            train_turning(
                bootstrap_planar(dataset, seed),
                model=model,
                training=training.replace(seed=seed),
                out=member,
                progress=told,
            )
        )
    return fits


def _turning_members(folder: PathLike) -> list[Path]:
    if not is_turning_ensemble(folder):
        raise DataFormatError(f"{folder}: not an ensemble of turning-body models (no turning ensemble.json)")
    return member_folders(folder)


def load_turning_ensemble(folder: PathLike) -> list[PlanarFHNN]:
    """The members :func:`train_turning_ensemble` wrote into ``folder``, in seed order.

    Raises:
        DataFormatError: ``folder`` is not a turning body's ensemble, or a member is missing
            (not trained yet) or unreadable.
    """
    return [load_turning(member) for member in _turning_members(folder)]


@dataclasses.dataclass(frozen=True)
class TurningIntervals:
    """What :func:`inspect_turning_ensemble` found.

    Attributes:
        coefficients: one row per quantity (``name, unit``): the added masses and per axis the
            equivalent linear damping (``X_d/u_r``: the least-squares ratio of the axis's damping
            force to its relative velocity over the covered velocities, ``over``); ``value`` the
            members' median, ``lo``, ``hi`` the interval; with a truth ``true``, ``rel_error`` of
            the median and ``inside`` (whether the interval holds the truth); for the damping also
            ``band_holds``, the fraction of covered velocities whose true force the pointwise
            interval holds.
        damping: one row per covered relative velocity: ``u_r, v_r, r_r`` (the members' median),
            per axis the members' median damping ``X_d, Y_d, N_d`` with ``_lo``, ``_hi`` and, with
            a truth, ``true_X_d, true_Y_d, true_N_d``.
        members: how many members.
        files: the paths written.
    """

    coefficients: pd.DataFrame
    damping: pd.DataFrame
    members: int
    files: tuple[Path, ...]


def _ratio(force: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The least-squares ratio ``Σ F v / Σ v²`` over the last axis."""
    return np.sum(force * speed, axis=-1) / np.sum(speed * speed, axis=-1)


def ensemble_coefficients(
    models: list[PlanarFHNN], dataset: PlanarDataset, max_points: int = 2000
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    """The coefficient rows and damping columns of :class:`TurningIntervals` for ``models`` (at
    least 2) on ``dataset``'s training split (the relative velocities: the members' median of
    :func:`~fhnn.evaluation.planar_coefficients.covered_relative_velocities`).

    Raises:
        ValueError: fewer than 2 models, or ``max_points`` below 1.
    """
    if len(models) < 2:
        raise ValueError(f"intervals need at least 2 members, got {len(models)}")
    nu_r = np.median(np.stack([covered_relative_velocities(m, dataset, max_points) for m in models]), axis=0)
    x = jnp.asarray(nu_r)
    forces = np.stack([np.asarray(jax.vmap(m.damping)(x)) for m in models])  # (N, P, 3)
    masses = np.stack([np.asarray(m.added_mass()) for m in models])  # (N, 3)
    true_force = np.asarray(jax.vmap(dataset.truth().damping())(x)) if dataset.has_truth else None
    true_mass = np.asarray(dataset.params["added_mass"], float) if dataset.has_truth else None
    rows: list[dict[str, Any]] = []

    def row(name: str, unit: str, values: np.ndarray, true: float | None) -> dict[str, Any]:
        median, lo, hi = interval(values)
        out = {"name": name, "unit": unit, "value": float(median), "lo": float(lo), "hi": float(hi)}
        if true is not None:
            error = abs(float(median) - true) / abs(true)
            out |= {"true": true, "rel_error": error, "inside": bool(lo <= true <= hi)}
        return out

    for i, (name, unit) in enumerate(MASSES):
        rows.append(row(name, unit, masses[:, i], None if true_mass is None else float(true_mass[i])))
    columns: dict[str, np.ndarray] = {axis[0]: nu_r[:, i] for i, axis in enumerate(AXES)}
    for i, ((speed, _, force, _), (name, unit)) in enumerate(zip(AXES, RATIOS, strict=True)):
        ratios = _ratio(forces[:, :, i], nu_r[None, :, i])
        true = None if true_force is None else float(_ratio(true_force[:, i], nu_r[:, i]))
        over = f"{speed} {nu_r[:, i].min():.3g} to {nu_r[:, i].max():.3g}"
        r = row(name, unit, ratios, true) | {"over": over}
        median, lo, hi = interval(forces[:, :, i])
        columns |= {force: median, f"{force}_lo": lo, f"{force}_hi": hi}
        if true_force is not None:
            columns[f"true_{force}"] = true_force[:, i]
            r["band_holds"] = float(np.mean((lo <= true_force[:, i]) & (true_force[:, i] <= hi)))
        rows.append(r)
    return rows, columns


def inspect_turning_ensemble(
    folder: PathLike,
    data: PlanarDataset | PathLike,
    *,
    out: PathLike | None = None,
    max_points: int = 2000,
) -> TurningIntervals:
    """Intervals (:data:`~fhnn.training.ensemble.LEVEL`) for the added masses and the damping of
    the ensemble in ``folder`` over the relative velocities of ``data``'s training split.

    Args:
        folder: the folder :func:`train_turning_ensemble` wrote.
        data: the data set it was trained on (or its HDF5 file), not a bootstrap.
        out: the folder to write ``coefficients.csv``, ``damping.csv`` and ``damping.png`` into
            (default ``folder``).
        max_points: at most this many covered relative velocities (an even subsample).

    Raises:
        DataFormatError: ``folder`` is not a complete turning ensemble, ``data`` not a turning
            body's data set, or ``out`` cannot be written.
        ConfigError: ``max_points`` is below 1.
    """
    if max_points < 1:
        raise ConfigError(f"max_points must be at least 1, got {max_points}")
    target = check_writable_folder(Path(out) if out is not None else Path(folder))
    models = load_turning_ensemble(folder)
    dataset = data if isinstance(data, PlanarDataset) else read_planar(data)
    rows, columns = ensemble_coefficients(models, dataset, max_points)
    coefficients = pd.DataFrame(rows)
    files = write_inspection(target, coefficients, columns)
    return TurningIntervals(coefficients, pd.DataFrame(columns), len(models), files)


def evaluate_turning_ensemble(
    folder: PathLike, data: PlanarDataset | PathLike, *, horizon: float = 5.0
) -> list[dict[str, Any]]:
    """Each member's :func:`fhnn.api.planar.evaluate_turning` report on ``data``, in seed order,
    each with its ``"member"`` (the folder's name).

    Raises:
        DataFormatError: ``folder`` is not a complete turning ensemble, or ``data`` not a turning
            body's data set.
    """
    from fhnn.api.planar import evaluate_turning

    dataset = data if isinstance(data, PlanarDataset) else read_planar(data)
    return [
        {"member": member.name} | evaluate_turning(load_turning(member), dataset, horizon=horizon)
        for member in _turning_members(folder)
    ]


def predict_turning_ensemble(
    folder: PathLike,
    history: Any,
    duration: float,
    *,
    dt: float | None = None,
    smoother: str = "auto",
    columns: Mapping[str, str] | str | None = None,
    time_unit: str = "s",
    output: PathLike | None = None,
) -> pd.DataFrame:
    """Every member's :func:`~fhnn.api.planar_predict.predict_turning` of ``history``, combined:
    per row the members' median and, for ``x, y, heading, u, v, r``, the interval ``_lo``,
    ``_hi`` (:func:`~fhnn.training.ensemble.interval`). A row is kept where every member's
    forecast reached it. Arguments, units and errors as :func:`predict_turning`'s; ``output``
    gets the columns ``traj_id, t``, each quantity and its ``_lo`` and ``_hi``.
    """
    if output is not None:
        check_output_path(check_table_name(output))
    members = _turning_members(folder)
    forecasts = [
        predict_turning(m, history, duration, dt=dt, smoother=smoother, columns=columns, time_unit=time_unit)
        for m in members
    ]
    keys = ["traj_id", "t"]
    common = forecasts[0][keys]
    for f in forecasts[1:]:
        common = common.merge(f[keys], on=keys)
    aligned = [common.merge(f, on=keys, how="left") for f in forecasts]
    combined: dict[str, np.ndarray] = {k: common[k].to_numpy() for k in keys}
    for name in COLUMNS[2:]:
        median, lo, hi = interval(np.stack([a[name].to_numpy() for a in aligned]))
        combined |= {name: median, f"{name}_lo": lo, f"{name}_hi": hi}
    if output is not None:
        write_table(combined, output)
    return pd.DataFrame(combined)


__all__ = [
    "LEVEL",
    "RATIOS",
    "TurningIntervals",
    "ensemble_coefficients",
    "evaluate_turning_ensemble",
    "inspect_turning_ensemble",
    "is_turning_ensemble",
    "load_turning_ensemble",
    "predict_turning_ensemble",
    "train_turning_ensemble",
]
