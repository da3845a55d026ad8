"""What a turning body's run learned (``fhnn turning inspect``): the added masses and the damping
over the relative velocities the data cover, as tables, files and a figure.

::

    from fhnn.api.planar_inspect import inspect_turning

    found = inspect_turning("runs/turning", "tracks.h5")  # writes into runs/turning
    found.coefficients  # pandas.DataFrame: m_11, m_22, m_66, d_11, d_22, d_66
    found.damping       # pandas.DataFrame: u_r, v_r, r_r, X_d, Y_d, N_d, ...
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np
import pandas as pd

from fhnn.api.planar import load_turning
from fhnn.api.planar_controls_files import is_controlled_run
from fhnn.data.planar import PlanarDataset, read_planar
from fhnn.errors import ConfigError, DataFormatError
from fhnn.evaluation.planar_coefficients import coefficient_rows, damping_samples
from fhnn.experiments.planar_damping_figure import damping_figure
from fhnn.files import atomic_output, check_writable_folder
from fhnn.models.planar import PlanarFHNN

#: The files :func:`inspect_turning` writes.
COEFFICIENTS_FILE, DAMPING_FILE, DAMPING_FIGURE = "coefficients.csv", "damping.csv", "damping.png"


@dataclasses.dataclass(frozen=True)
class TurningCoefficients:
    """What :func:`inspect_turning` found.

    Attributes:
        coefficients: one row per quantity (``name, unit``): the added masses' ``value``; per
            axis the diagonal damping coefficient's ``low`` and ``high`` over the covered relative
            velocities (``over``); with a truth, ``true`` and ``rel_error`` (for the damping: the
            relative L2 error of its force over those velocities).
        damping: one row per covered relative velocity: ``u_r, v_r, r_r`` [m/s, m/s, rad/s], the
            damping ``X_d, Y_d, N_d`` [N, N, N·m], ``d_11, d_22, d_66`` and, with a truth,
            ``true_X_d, true_Y_d, true_N_d``.
        files: the paths written (none when nothing was asked to be written).
    """

    coefficients: pd.DataFrame
    damping: pd.DataFrame
    files: tuple[Path, ...]


def inspect_turning(
    run: PlanarFHNN | str | os.PathLike[str],
    data: PlanarDataset | str | os.PathLike[str],
    *,
    out: str | os.PathLike[str] | None = None,
    max_points: int = 2000,
) -> TurningCoefficients:
    """The added masses and the damping of a turning body's model over the relative velocities
    of ``data``'s training split (:mod:`fhnn.evaluation.planar_coefficients`).

    Args:
        run: a model, or the folder :func:`fhnn.api.planar.train_turning` wrote.
        data: the data set it was trained on (or its HDF5 file).
        out: the folder to write ``coefficients.csv``, ``damping.csv`` and ``damping.png`` into;
            by default ``run`` when it is a folder, else nothing is written.
        max_points: at most this many covered relative velocities (an even subsample).

    Raises:
        DataFormatError: ``run`` or ``data`` is not a turning body's (a run of logged controls is
            refused: its masses and damping are not fixed by such data), or ``out`` cannot be
            written.
        ConfigError: ``max_points`` is below 1.
    """
    if max_points < 1:
        raise ConfigError(f"max_points must be at least 1, got {max_points}")
    folder = Path(out) if out is not None else (None if isinstance(run, PlanarFHNN) else Path(run))
    if folder is not None:
        check_writable_folder(folder)
    if not isinstance(run, PlanarFHNN) and is_controlled_run(run):
        raise DataFormatError(
            f"{run}: a model of logged controls, whose added masses and damping the data do not fix; "
            "`fhnn turning evaluate` scores its forecasts"
        )
    model = run if isinstance(run, PlanarFHNN) else load_turning(run)
    dataset = data if isinstance(data, PlanarDataset) else read_planar(data)
    samples = damping_samples(model, dataset, max_points)
    found = TurningCoefficients(
        pd.DataFrame(coefficient_rows(model, dataset, samples)), pd.DataFrame(samples), ()
    )
    if folder is None:
        return found
    return dataclasses.replace(found, files=write_inspection(folder, found.coefficients, samples))


def write_inspection(
    folder: Path, coefficients: pd.DataFrame, samples: dict[str, np.ndarray]
) -> tuple[Path, ...]:
    """Write ``coefficients.csv`` (``coefficients``), ``damping.csv`` (the columns ``samples``)
    and ``damping.png`` (:func:`~fhnn.experiments.planar_damping_figure.damping_figure` of
    ``samples``) into ``folder``, each whole or not at all; returns their paths."""
    written = []
    for name, table in ((COEFFICIENTS_FILE, coefficients), (DAMPING_FILE, pd.DataFrame(samples))):
        with atomic_output(folder / name) as tmp:
            table.to_csv(tmp, index=False)
        written.append(folder / name)
    written.append(damping_figure(samples, folder / DAMPING_FIGURE))
    return tuple(written)


__all__ = [
    "COEFFICIENTS_FILE",
    "DAMPING_FIGURE",
    "DAMPING_FILE",
    "TurningCoefficients",
    "inspect_turning",
    "write_inspection",
]
