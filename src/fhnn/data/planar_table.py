"""A user's table of a body that turns, into a :class:`~fhnn.data.planar.PlanarDataset`
(``fhnn import`` of a table with a ``heading`` column).

The table has one row per sample, in any order, with the columns (SI units throughout):

======================  ======================================================================
``traj_id``             which trajectory the row belongs to (any integers or strings)
``t``                   sample time [s], or ISO-8601 date-times, as for a point body's table
                        (:mod:`fhnn.data.table`); each trajectory has its own, irregular times
``x``, ``y``            position of the tracked point (the body frame's origin) [m]
``heading``             ψ [rad], counter-clockwise from the x-axis (any branch: it is unwrapped)
``Fu``, ``Fv``          known force along the body's forward and port axes [N] — optional, both
                        or neither
``Mz``                  known yaw moment about the tracked point [N·m] — optional, only with
                        ``Fu, Fv``
``Fx``, ``Fy``          known force in the world frame [N] — optional, both or neither, instead
                        of ``Fu, Fv``; turned into the body frame by the estimated heading
======================  ======================================================================

Rows with a missing value are gaps, dropped and counted. Positions and heading carry noise; the
noise of each is estimated (:func:`~fhnn.data.derivatives.noise_level`) and the pose and its rate
come from a smoother held to that noise (:mod:`fhnn.data.derivatives`: the positions as one
curve, the heading on its own). The body-frame velocity is ``(u, v) = R(ψ̂)ᵀ (ẋ̂, ŷ̂)``, ``r = ψ̂̇``.
Forces are read linearly between samples, in the body frame.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.data.conversion import split_counts
from fhnn.data.derivatives import _kalman_fit, _spline_fit, choose_smoother, noise_level
from fhnn.data.planar import PlanarDataset, PlanarSplit
from fhnn.data.table import (
    MIN_SAMPLES,
    PAD_STEP,
    _numeric,
    _open,
    _reject_infinite,
    _reject_same_times,
    _times,
    _trajectory_ids,
    time_unit_seconds,
)
from fhnn.errors import ConfigError, DataFormatError

REQUIRED = ("traj_id", "t", "x", "y", "heading")
BODY_FORCE = ("Fu", "Fv")
WORLD_FORCE = ("Fx", "Fy")
COLUMNS = (*REQUIRED, *BODY_FORCE, "Mz", *WORLD_FORCE)
#: The scenario name an imported data set carries.
IMPORTED = "imported"


@dataclasses.dataclass(frozen=True)
class PlanarTrajectory:
    """One trajectory of a table: its id, times ``t`` ``(n,)`` [s], observed pose ``(n, 3)``
    ``(x, y, ψ)`` [m, m, rad] with the heading unwrapped, and the known force: body-frame
    ``(n, 3)`` ``(X, Y, N)`` [N, N, N·m], or world-frame ``(n, 2)`` [N], or ``None``."""

    traj_id: str
    t: np.ndarray
    pose: np.ndarray
    body_force: np.ndarray | None
    world_force: np.ndarray | None


@dataclasses.dataclass(frozen=True)
class PlanarTable:
    """The trajectories of a table, sorted by id, the table's rows and the gap rows dropped."""

    trajectories: list[PlanarTrajectory]
    rows: int
    dropped: int
    time_origin: str | None = None


def has_heading(table: str | os.PathLike[str] | Any, columns: Mapping[str, str] | None = None) -> bool:
    """Whether ``table`` (a .csv or .parquet path, or a ``pandas.DataFrame``) has a ``heading``
    column, by ``columns``' names (ours → theirs) where given: a body that turns."""
    name = (columns or {}).get("heading", "heading")
    if not isinstance(table, str | os.PathLike):
        return name in getattr(table, "columns", ())
    from fhnn.data.table import _csv_header

    path = Path(table)
    if path.suffix.lower() not in (".csv", ".parquet"):
        return False  # the reader names the problem
    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq

        try:
            return name in pq.read_schema(path).names
        except (OSError, ValueError):
            return False  # the reader names the problem
    return name in [n.strip() for n in _csv_header(path)[1]]


def read_planar_table(
    path: str | os.PathLike[str] | Any,
    *,
    columns: Mapping[str, str] | None = None,
    time_unit: str = "s",
    origin: str | None = None,
) -> PlanarTable:
    """Read and check a turning body's table (see the module docstring).

    Args:
        path: a .csv or .parquet path, or a ``pandas.DataFrame``.
        columns: the table's names of our columns where they differ (ours → theirs).
        time_unit: the unit of numeric times (:data:`~fhnn.data.table.TIME_UNITS`).
        origin: date-times count in seconds from this date-time; default: the table's earliest.

    Raises:
        ConfigError: an unknown ``time_unit``.
        DataFormatError: a missing column (``x``/``y`` included: a heading needs positions), a
            force without its partner (``Fu`` without ``Fv``), ``Mz`` without ``Fu, Fv``, forces
            in both frames, an unknown column, a non-numeric or infinite value, two rows of one
            trajectory at one time, or a trajectory of fewer than
            :data:`~fhnn.data.table.MIN_SAMPLES` samples.
    """
    scale = time_unit_seconds(time_unit)
    path, arrow, names = _open(path, "a table", REQUIRED, COLUMNS, columns)
    for a, b in (BODY_FORCE, WORLD_FORCE):
        if (a in names) != (b in names):
            raise DataFormatError(
                f"{path}: column {a if a not in names else b!r} is missing: give {a} and {b}, or neither"
            )
    if "Mz" in names and "Fu" not in names:
        raise DataFormatError(f"{path}: column 'Mz' needs the body-frame forces Fu and Fv beside it")
    if "Fu" in names and "Fx" in names:
        raise DataFormatError(f"{path}: give the known force in one frame: Fu, Fv (body) or Fx, Fy (world)")
    rows = arrow.num_rows
    if rows == 0:
        raise DataFormatError(f"{path}: the table has no rows")
    ids, rank = _trajectory_ids(arrow.column("traj_id"))
    times, origin = _times(path, arrow.column("t"), origin)
    if scale != 1.0:
        if origin is not None:
            raise ConfigError(f"--time-unit {time_unit} applies to numeric times; {path} gives date-times")
        times = times * scale
    values = {c: times if c == "t" else _numeric(path, c, arrow.column(c)) for c in names if c != "traj_id"}
    _reject_infinite(path, values, ids)
    gap = (ids == "") | np.any([np.isnan(v) for v in values.values()], axis=0)
    keep = np.flatnonzero(~gap)
    if keep.size == 0:
        raise DataFormatError(f"{path}: every row has a missing value")
    order = keep[np.lexsort((values["t"][keep], rank[keep]))]
    starts = np.flatnonzero(np.r_[True, rank[order][1:] != rank[order][:-1]])
    trajectories = []
    for a, b in zip(starts, np.r_[starts[1:], order.size], strict=True):
        rows_of = order[a:b]
        traj_id = str(ids[rows_of[0]])
        t = values["t"][rows_of]
        _reject_same_times(path, t, rows_of, f"trajectory {traj_id!r}: ")
        if t.size < MIN_SAMPLES:
            raise DataFormatError(
                f"{path}: trajectory {traj_id!r} has {t.size} sample(s) (row {int(rows_of[0]) + 1}); "
                f"at least {MIN_SAMPLES} are needed"
            )
        heading = np.unwrap(values["heading"][rows_of])
        pose = np.stack([values["x"][rows_of], values["y"][rows_of], heading], axis=1)
        body = world = None
        if "Fu" in names:
            moment = values["Mz"][rows_of] if "Mz" in names else np.zeros(t.size)
            body = np.stack([values["Fu"][rows_of], values["Fv"][rows_of], moment], axis=1)
        if "Fx" in names:
            world = np.stack([values["Fx"][rows_of], values["Fy"][rows_of]], axis=1)
        trajectories.append(PlanarTrajectory(traj_id, t, pose, body, world))
    return PlanarTable(trajectories, rows, int(gap.sum()), origin)


@dataclasses.dataclass(frozen=True)
class PlanarImportSettings:
    """What a turning body's table does not say.

    Attributes:
        mass: the body's mass ``m`` [kg]; inertia: its yaw moment of inertia ``I_z`` about the
            tracked point [kg·m²]; x_g: its centre of gravity ahead of the tracked point [m].
        split: fractions of the trajectories for train, val and test (each > 0, summing to 1).
        seed: seed of the split's permutation.
        time_dependent: whether models may let the flow depend on time.
        smoother: ``"spline"``, ``"kalman"`` or ``"auto"``
            (:func:`~fhnn.data.derivatives.choose_smoother`).
    """

    mass: float
    inertia: float
    x_g: float = 0.0
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)
    seed: int = 0
    time_dependent: bool = False
    smoother: str = "auto"

    def __post_init__(self) -> None:
        choose_smoother(self.smoother, 0)
        for name in ("mass", "inertia"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"--{name} must be a positive number, got {value!r}")
        if not math.isfinite(self.x_g):
            raise ConfigError(f"x_g must be a finite number, got {self.x_g!r}")
        fractions = self.split
        if len(fractions) != 3 or not all(f > 0 for f in fractions) or not math.isclose(sum(fractions), 1.0):
            raise ConfigError(f"split must be three positive fractions summing to 1, got {self.split!r}")


def _smoothed(
    trajectories: list[PlanarTrajectory], smoother: str
) -> tuple[list[np.ndarray], list[np.ndarray], float, float]:
    """Each trajectory's smoothed pose and its rate, ``(n, 3)`` each, and the estimated noise
    of the positions [m] and of the heading [rad]."""
    positions = [(tr.t, tr.pose[:, k]) for tr in trajectories for k in range(2)]
    headings = [(tr.t, tr.pose[:, 2]) for tr in trajectories]
    noise_pos, noise_psi = noise_level(positions), noise_level(headings)
    fit = _spline_fit if smoother == "spline" else _kalman_fit
    xy, psi = fit(positions, noise_pos), fit(headings, noise_psi)
    poses, rates = [], []
    for i in range(len(trajectories)):
        parts = (xy[2 * i], xy[2 * i + 1], psi[i])
        poses.append(np.stack([p[:, 0] for p in parts], axis=1))
        rates.append(np.stack([p[:, 1] for p in parts], axis=1))
    return poses, rates, noise_pos, noise_psi


def _padded(items: list[np.ndarray], size: int, times: bool = False) -> np.ndarray:
    """``items`` (each ``(n_i, …)``) stacked to ``(N, size, …)``: times go on in steps of
    :data:`~fhnn.data.table.PAD_STEP`, anything else repeats its last entry."""
    out = []
    for a in items:
        extra = size - a.shape[0]
        tail = a[-1] + PAD_STEP * np.arange(1, extra + 1) if times else np.repeat(a[-1:], extra, axis=0)
        out.append(np.concatenate([a, tail]))
    return np.stack(out)


def planar_table_to_dataset(table: PlanarTable, settings: PlanarImportSettings) -> PlanarDataset:
    """The data set of ``table``: trajectories split by a seeded permutation, the pose smoothed
    and the body-frame velocity estimated (module docstring), forces in the body frame.

    Raises:
        DataFormatError: fewer than three trajectories.
    """
    trajs = table.trajectories
    counts = split_counts(len(trajs), settings.split)
    smoother = choose_smoother(settings.smoother, sum(tr.t.size for tr in trajs))
    poses, rates, noise_pos, noise_psi = _smoothed(trajs, smoother)
    order = np.random.default_rng(settings.seed).permutation(len(trajs))
    ends = np.cumsum(counts)
    names = ("train", "val", "test")
    parts = {name: order[end - n : end] for name, n, end in zip(names, counts, ends, strict=True)}
    splits = {}
    for name, chosen in parts.items():
        t, states, reference, forces = [], [], [], []
        for i in chosen:
            tr, pose, rate = trajs[i], poses[i], rates[i]
            c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
            nu = np.stack([c * rate[:, 0] + s * rate[:, 1], -s * rate[:, 0] + c * rate[:, 1], rate[:, 2]], 1)
            if tr.body_force is not None:
                force = tr.body_force
            elif tr.world_force is not None:
                fx, fy = tr.world_force[:, 0], tr.world_force[:, 1]
                force = np.stack([c * fx + s * fy, -s * fx + c * fy, np.zeros_like(fx)], axis=1)
            else:
                force = np.zeros((tr.t.size, 3))
            t.append(tr.t)
            states.append(np.concatenate([pose, nu], axis=1))
            reference.append(np.concatenate([tr.pose, nu], axis=1))
            forces.append(force)
        size = max(a.size for a in t)
        splits[name] = PlanarSplit(
            t=_padded(t, size, times=True),
            states=_padded(states, size),
            states_clean=_padded(reference, size),
            forces=_padded(forces, size),
            thrust=np.zeros((len(chosen), 3, 3, 3)),
            lengths=np.asarray([a.size for a in t]),
        )
    params = {
        "time_dependent": settings.time_dependent,
        "noise": {"position": noise_pos, "heading": noise_psi},
        "smoother": smoother,
        "rows": table.rows,
        "dropped": table.dropped,
        "time_origin": table.time_origin,
        "ids": {name: [trajs[i].traj_id for i in chosen] for name, chosen in parts.items()},
    }
    return PlanarDataset(
        IMPORTED, params, settings.seed, noise_pos, settings.mass, settings.inertia, settings.x_g, splits
    )


def observed_table(
    dataset: PlanarDataset,
    *,
    position_noise: float = 0.0,
    heading_noise: float = 0.0,
    steps: tuple[int, int] = (1, 1),
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """A table of ``dataset``'s noise-free trajectories (every split, ids ``split-i``) as a tracker
    would give it: every ``k``-th sample with ``k`` drawn uniformly from ``steps`` (irregular
    times), Gaussian noise of std ``position_noise`` [m] on ``x, y`` and ``heading_noise`` [rad] on
    the heading, and the known body-frame forces ``Fu, Fv, Mz``. Returns the columns by name (for
    :func:`~fhnn.data.table.write_table` or ``pandas.DataFrame``)."""
    rng = np.random.default_rng(seed)
    names = ("traj_id", "t", "x", "y", "heading", "Fu", "Fv", "Mz")
    columns: dict[str, list[np.ndarray]] = {k: [] for k in names}
    for name, split in dataset.splits.items():
        for i in range(split.t.shape[0]):
            n = int(split.lengths[i])
            picks = np.cumsum(rng.integers(steps[0], steps[1] + 1, n))
            picks = np.r_[0, picks[picks < n]]
            clean = split.states_clean[i, picks]
            columns["traj_id"].append(np.full(picks.size, f"{name}-{i}"))
            columns["t"].append(split.t[i, picks])
            columns["x"].append(clean[:, 0] + rng.normal(0.0, position_noise, picks.size))
            columns["y"].append(clean[:, 1] + rng.normal(0.0, position_noise, picks.size))
            columns["heading"].append(clean[:, 2] + rng.normal(0.0, heading_noise, picks.size))
            for k, key in enumerate(("Fu", "Fv", "Mz")):
                columns[key].append(split.forces[i, picks, k])
    return {k: np.concatenate(v) for k, v in columns.items()}


__all__ = [
    "IMPORTED",
    "PlanarImportSettings",
    "PlanarTable",
    "PlanarTrajectory",
    "has_heading",
    "observed_table",
    "planar_table_to_dataset",
    "read_planar_table",
]
