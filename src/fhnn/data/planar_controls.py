"""A turning body's table whose forcing is logged controls (rudder angle, propeller speed, …), not
forces.

The table is a turning body's table (:mod:`fhnn.data.planar_table`: ``traj_id, t, x, y,
heading``) with one to three control columns, named by the user, in any units, and no force
columns. The controls travel in the data set's forces channel (``PlanarSplit.forces[..., k]`` is
the ``k``-th control, unused slots zero), read linearly between samples like forces, for a model
that maps them to forces (:class:`~fhnn.models.planar_actuated.ActuatedPlanarFHNN`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from fhnn.data.planar_table import BODY_FORCE, COLUMNS, REQUIRED, WORLD_FORCE
from fhnn.errors import DataFormatError

#: The forces channel's slots the controls fill, in order.
SLOTS = ("Fu", "Fv", "Mz")


def _frame(table: str | os.PathLike[str] | pd.DataFrame) -> tuple[pd.DataFrame, str]:
    if isinstance(table, pd.DataFrame):
        return table, "the table"
    path = Path(table)
    if not path.is_file():
        raise DataFormatError(f"{path}: no such file")
    try:
        if path.suffix == ".parquet":
            return pd.read_parquet(path), str(path)
        if path.suffix == ".csv":
            return pd.read_csv(path), str(path)
    except (OSError, ValueError) as err:
        raise DataFormatError(f"{path}: not a readable table ({str(err).splitlines()[0]})") from None
    raise DataFormatError(f"{path}: a table is a .csv or .parquet file")


def controls_as_forcing(
    table: str | os.PathLike[str] | pd.DataFrame,
    controls: Sequence[str],
    columns: Mapping[str, str] | None = None,
) -> pd.DataFrame:
    """``table`` with its ``controls`` columns moved into the forces slots ``Fu, Fv, Mz`` (in
    order, unused slots zero) and every other column but the turning body's own left out.

    Args:
        table: a .csv or .parquet path, or a ``pandas.DataFrame``.
        controls: the control columns' names, one to three, distinct.
        columns: the table's names of the turning body's columns where they differ (ours →
            theirs, as :func:`fhnn.data.table.parse_columns` gives them).

    Raises:
        DataFormatError: no controls or more than three, a name given twice, a control that is a
            column of the turning body's table (``x``, ``Fu``, …), a control the table lacks or
            whose values are not numbers, or a table that gives forces as well (forces and
            controls are two ways to give the forcing; give one).
    """
    frame, name = _frame(table)
    if columns:
        frame = frame.rename(columns={theirs: ours for ours, theirs in columns.items() if ours in COLUMNS})
    controls = list(controls)
    if not 1 <= len(controls) <= len(SLOTS):
        raise DataFormatError(f"give one to {len(SLOTS)} control columns, got {len(controls)}")
    if len(set(controls)) != len(controls):
        raise DataFormatError(f"a control column is named twice: {', '.join(controls)}")
    reserved = [c for c in controls if c in COLUMNS]
    if reserved:
        raise DataFormatError(f"{reserved[0]!r} is a column of the turning body's table, not a control")
    missing = [c for c in controls if c not in frame.columns]
    if missing:
        raise DataFormatError(
            f"{name}: no control column {missing[0]!r} (columns: {', '.join(map(str, frame.columns))})"
        )
    text = [c for c in controls if not pd.api.types.is_numeric_dtype(frame[c])]
    if text:
        raise DataFormatError(f"{name}: control column {text[0]!r} is not numeric")
    forces = [c for c in (*BODY_FORCE, "Mz", *WORLD_FORCE) if c in frame.columns]
    if forces:
        raise DataFormatError(f"{name}: gives forces ({', '.join(forces)}) and controls; give one of them")
    out = frame[[c for c in REQUIRED if c in frame.columns]].copy()
    for slot, control in zip(SLOTS, controls + [None] * (len(SLOTS) - len(controls)), strict=True):
        out[slot] = frame[control] if control is not None else 0.0
    return out


__all__ = ["SLOTS", "controls_as_forcing"]
