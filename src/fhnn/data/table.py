"""A user's measured trajectories, from a CSV or Parquet table into a data set (``fhnn import``).

The table has one row per sample, in any order, with the columns (SI units throughout):

======================  ======================================================================
``traj_id``             which trajectory the row belongs to (any integers or strings)
``t``                   sample time [s], or ISO-8601 date-times (``2026-03-01T10:00:00.25``, all
                        with a zone such as ``Z`` or ``+02:00``, or all without), read as seconds
                        after the table's earliest one (kept as ``time_origin`` in the import
                        record); each trajectory has its own, irregular times
``x``, ``y``            position [m]
``vx``, ``vy``          velocity [m/s] — optional, both or neither; estimated where absent
``Fx``, ``Fy``          known external force [N] — optional, both or neither; zero where absent
======================  ======================================================================

A CSV file's columns may be separated by commas, semicolons or tabs (whichever its header line
uses most), and spaces around the header's names are ignored.

Rows with a missing value (an empty cell or NaN) in any column present are gaps: they are dropped
and counted. A track with an outage — two samples further apart than ``--max-gap`` — becomes pieces
(:func:`split_at_gaps`), and a position far from the cubic through its neighbours — a tracker's
glitch, ``--outliers`` — is dropped and counted (:func:`drop_outliers`). Any other problem — a
missing or unknown column, a non-numeric or infinite value, two rows of one trajectory at the same
time, a trajectory with fewer than :data:`MIN_SAMPLES` samples — is a
:class:`~fhnn.errors.DataFormatError` naming the column, the trajectory and the row (the row number
counts data rows from 1, the header not included).

Velocities absent from the table, and every acceleration, are estimated
(:mod:`fhnn.data.derivatives`: by default a smoothing spline, the Kalman smoother above 200,000
rows, held to the noise level the positions show), and the estimated velocities' RMS error is
kept beside the noise level in the import record (``velocity_error``, a parametric bootstrap of
the smoother: :func:`~fhnn.data.derivatives.derivative_error`); the data
set's ``measured`` attribute says which fields were measured, and training then leaves out the
derivative loss (whose targets would be estimates). Trajectories are split into train, val and
test by a seeded permutation.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.data.dataset import IMPORTED, SPLITS, Dataset, Split
from fhnn.data.derivatives import (
    AUTO,
    choose_smoother,
    derivative_error,
    lagrange_residuals,
    noise_level,
    smooth_derivatives,
)
from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import atomic_output, check_input_file
from fhnn.runtime import __version__

REQUIRED = ("traj_id", "t", "x", "y")
OPTIONAL_PAIRS = (("vx", "vy"), ("Fx", "Fy"))
COLUMNS = (*REQUIRED, *(c for pair in OPTIONAL_PAIRS for c in pair))
#: Fewest samples a trajectory may have (velocity and noise estimates need neighbours).
MIN_SAMPLES = 3
#: Padding after a shorter trajectory's last sample: times go on in steps of this [s].
PAD_STEP = 1e-6
#: ``--max-gap auto``: a track is split where an interval is longer than this many times its
#: median step. Training rolls RK4 one step per interval; on issue 14's tracks (``steady_vortex``
#: observed every 0.05 s) one step's position error is at most 8.0e-6 m over 10 steps' time
#: (0.5 s), 2.2e-4 m over 20 and 5.7e-3 m over 40, against 1 mm of noise
#: (``benchmarks/gap_steps.py``, ``docs/benchmarks/gap_steps.txt``).
GAP_STEPS = 10.0
#: ``--outliers``' default: a position more than this many noise levels from the cubic through its
#: two neighbours either side is a glitch and is dropped (:func:`drop_outliers`). Pure noise goes
#: past 8σ about once in 10^15 samples; issue 14's tracks (1 mm noise, 0.05 s steps) reach 4.2σ.
OUTLIER_SIGMAS = 8.0
#: Passes of :func:`drop_outliers` over a track at most (each drops the worst sample of every
#: cluster of flagged ones).
OUTLIER_PASSES = 20


@dataclasses.dataclass(frozen=True)
class Trajectory:
    """One trajectory of a table: its id, times ``t`` ``(n,)`` [s], positions ``(n, 2)`` [m],
    velocities ``(n, 2)`` [m/s] or ``None``, forces ``(n, 2)`` [N] or ``None``."""

    traj_id: str
    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray | None
    force: np.ndarray | None

    def take(self, index: np.ndarray | slice, traj_id: str | None = None) -> Trajectory:
        """The samples ``index`` (a mask, indices or a slice) of this trajectory, named
        ``traj_id`` (default: its own id)."""
        pick = lambda a: None if a is None else a[index]  # noqa: E731
        return Trajectory(
            self.traj_id if traj_id is None else traj_id,
            self.t[index],
            self.pos[index],
            pick(self.vel),
            pick(self.force),
        )


def _position_series(trajectories: list[Trajectory]) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(t, x), (t, y)]`` of every trajectory, in order: the series
    :func:`~fhnn.data.derivatives.noise_level` and the smoothers take."""
    return [(tr.t, tr.pos[:, k]) for tr in trajectories for k in range(2)]


@dataclasses.dataclass(frozen=True)
class Table:
    """The trajectories of a table, sorted by id, and the number of gap rows dropped."""

    trajectories: list[Trajectory]
    rows: int
    dropped: int
    time_origin: str | None = None


#: Delimiters a CSV file's header line is checked for (the most frequent one is used).
DELIMITERS = (",", ";", "\t")


def _csv_header(path: Path) -> tuple[str, list[str]]:
    """The delimiter a CSV file's header line uses most (a comma where it has none) and the
    header's names as written."""
    import csv

    try:
        with open(path, encoding="utf-8-sig", errors="replace", newline="") as f:
            line = f.readline(1 << 16)
    except OSError:  # reported by the reader
        return ",", []
    delimiter = max(DELIMITERS, key=line.count) if any(d in line for d in DELIMITERS) else ","
    return delimiter, next(csv.reader([line], delimiter=delimiter), [])


def _read_arrow(path: Path) -> Any:
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    suffix = path.suffix.lower()
    try:
        if suffix == ".parquet":
            table = pq.read_table(path)
        elif suffix == ".csv":
            delimiter, header = _csv_header(path)
            # traj_id as text (ids like 007 stay themselves); every other column inferred
            traj_id = next((name for name in header if name.strip() == "traj_id"), "traj_id")
            options = pacsv.ConvertOptions(column_types={traj_id: pa.string()}, strings_can_be_null=False)
            table = pacsv.read_csv(
                path, parse_options=pacsv.ParseOptions(delimiter=delimiter), convert_options=options
            )
        else:
            raise DataFormatError(f"{path}: unknown table type {path.suffix!r}; give a .csv or .parquet file")
    except (pa.ArrowInvalid, OSError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataFormatError(f"{path}: not a readable table ({first})") from None
    names = [str(name).strip() for name in table.column_names]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        raise DataFormatError(f"{path}: column(s) {', '.join(twice)} appear more than once")
    return table.rename_columns(names)


#: The ``origin`` of :func:`read_table` and :func:`read_forcing` for a clock in seconds, with no
#: date-time origin: a table of date-times is then an error.
SECONDS_ONLY = ""

#: A value that starts like an ISO-8601 date, and one that ends with a zone ("Z", "+02:00").
_DATE = r"^\s*\d{4}-\d{2}-\d{2}"
_ZONE = r"(Z|[+-]\d{2}:?\d{2})\s*$"


def _times(path: Path, column: Any, origin: str | None = None) -> tuple[np.ndarray, str | None]:
    """The time column in seconds (nulls as NaN) and, where it holds ISO-8601 date-times, the
    date-time the seconds count from, as text: ``origin`` where given (a date-time as this
    function returns one), else the earliest of the column's; numbers are returned as they are.
    A column of date-times with a value that is not one, or with zones on some rows only, or
    where ``origin`` is :data:`SECONDS_ONLY`, is an error (naming the row)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if pa.types.is_timestamp(column.type):
        stamps = column
    elif (pa.types.is_string(column.type) or pa.types.is_large_string(column.type)) and pc.any(
        pc.match_substring_regex(column, _DATE)
    ).as_py():
        text = pc.if_else(pc.equal(pc.utf8_trim_whitespace(column), ""), pa.scalar(None, column.type), column)
        text = text.combine_chunks() if hasattr(text, "combine_chunks") else text
        zoned = np.asarray(pc.match_substring_regex(text, _ZONE).to_numpy(zero_copy_only=False), dtype=object)
        with_zone, without = np.flatnonzero(zoned == True), np.flatnonzero(zoned == False)  # noqa: E712 (nulls)
        if with_zone.size and without.size:
            raise DataFormatError(
                f"{path}: column 't': row {with_zone[0] + 1} has a time zone and row {without[0] + 1} has "
                "none; give every date-time with a zone or every one without"
            )
        kind = pa.timestamp("ns", tz="UTC") if with_zone.size else pa.timestamp("ns")
        try:
            stamps = pc.cast(text, kind)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            lo, hi = 0, len(text)  # a value that does not parse lies in [lo, hi): halve it
            while hi - lo > 1:
                mid = (lo + hi) // 2
                try:
                    pc.cast(text.slice(lo, mid - lo), kind)
                    lo = mid
                except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                    hi = mid
            raise DataFormatError(
                f"{path}: column 't', row {lo + 1}: {text[lo].as_py()!r} is not an ISO-8601 date-time"
            ) from None
    else:
        return _numeric(path, "t", column), None
    ns = pc.cast(pc.cast(stamps, pa.timestamp("ns", tz=getattr(stamps.type, "tz", None))), pa.int64())
    valid = ~np.asarray(pc.is_null(ns).to_numpy(zero_copy_only=False), dtype=bool)
    values = np.asarray(pc.fill_null(ns, 0).to_numpy(zero_copy_only=False), dtype=np.int64)
    zone = "Z" if getattr(stamps.type, "tz", None) else ""
    if origin == SECONDS_ONLY:
        raise DataFormatError(
            f"{path}: column 't' holds date-times, but the run's clock counts seconds (it was "
            "trained on times in seconds): give t in seconds on that clock"
        )
    if origin is not None:
        if origin.endswith("Z") != bool(zone):
            raise DataFormatError(
                f"{path}: column 't': its date-times are {'with' if zone else 'without'} a time zone "
                f"and the run's clock ({origin}) is {'without' if zone else 'with'}; give them alike"
            )
        start = _origin_ns(origin)
    else:
        start = int(values[valid].min()) if valid.any() else 0
    seconds = np.where(valid, (values - start) / 1e9, np.nan)
    return seconds, origin if origin is not None else date_time(start, zone)


def _origin_ns(origin: str) -> int:
    """The date-time ``origin`` (as :func:`_times` returns it, "Z" for UTC) in nanoseconds since 1970."""
    return int(np.datetime64(origin.removesuffix("Z"), "ns").astype(np.int64))


def date_time(ns: int | np.ndarray, zone: str = "") -> Any:
    """Nanoseconds since 1970 as ISO-8601 text (one value or an array of them), to the coarsest
    unit (s, ms, us, ns) that holds every value exactly, with ``zone`` ("Z" or "") appended."""
    values = np.atleast_1d(np.asarray(ns, dtype=np.int64))
    unit = next(
        u for u, q in (("s", 10**9), ("ms", 10**6), ("us", 10**3), ("ns", 1)) if np.all(values % q == 0)
    )
    text = np.char.add(np.datetime_as_string(values.astype("datetime64[ns]"), unit=unit).astype(str), zone)
    return str(text[0]) if np.ndim(ns) == 0 else text


def dataset_clock(dataset: Dataset) -> dict[str, Any]:
    """How a data set's times relate to the table it was imported from: ``{"origin": the
    date-time the table's seconds count from (None: the table gave seconds), "offset": seconds of
    that clock at the data set's t = 0}`` (its ``import`` record); origin None and offset 0 for a
    simulated one."""
    record = dataset.extra.get("import") or {}
    return {"origin": record.get("time_origin"), "offset": float(record.get("time_offset", 0.0))}


def shift_times(table: Table, seconds: float) -> Table:
    """``table`` with every sample time moved by ``seconds``."""
    moved = [dataclasses.replace(tr, t=tr.t + seconds) for tr in table.trajectories]
    return dataclasses.replace(table, trajectories=moved)


def seconds_to_date_times(seconds: np.ndarray, origin: str) -> np.ndarray:
    """``seconds`` after the date-time ``origin`` (as :func:`_times` returns it) as ISO-8601 text
    (rounded to the nanosecond), with ``origin``'s zone."""
    ns = _origin_ns(origin) + np.round(np.asarray(seconds, dtype=float) * 1e9).astype(np.int64)
    return date_time(ns, "Z" if origin.endswith("Z") else "")


def _numeric(path: Path, name: str, column: Any) -> np.ndarray:
    """The column as float64 (nulls as NaN); a non-numeric entry is an error naming its row."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if pa.types.is_integer(column.type) or pa.types.is_floating(column.type) or pa.types.is_null(column.type):
        return np.asarray(pc.cast(column, pa.float64()).to_numpy(zero_copy_only=False), dtype=float)
    for row, value in enumerate(column.to_pylist(), start=1):
        if value is None or value == "":
            continue
        try:
            float(value)
        except (TypeError, ValueError):
            what = "a number of seconds or an ISO-8601 date-time" if name == "t" else "a number"
            raise DataFormatError(f"{path}: column {name!r}, row {row}: {value!r} is not {what}") from None
    values = [np.nan if v in (None, "") else float(v) for v in column.to_pylist()]
    return np.asarray(values, dtype=float)


def _pair(values: dict[str, np.ndarray], a: str, b: str, rows: np.ndarray) -> np.ndarray | None:
    """Columns ``a`` and ``b`` at ``rows`` as an ``(n, 2)`` array (``None`` if the table lacks them)."""
    return np.stack([values[a][rows], values[b][rows]], axis=1) if a in values else None


def _frame_to_arrow(frame: Any) -> tuple[Path, Any]:
    """A ``pandas.DataFrame`` (or an Arrow table) as an Arrow table, ``traj_id`` as text, named
    ``DataFrame`` in messages."""
    import pyarrow as pa

    try:
        arrow = frame if isinstance(frame, pa.Table) else pa.Table.from_pandas(frame, preserve_index=False)
    except (TypeError, ValueError, pa.ArrowException) as exc:
        raise DataFormatError(
            f"not a table (a pandas DataFrame, or a .csv or .parquet path): {exc}"
        ) from None
    names = [str(name).strip() for name in arrow.column_names]
    arrow = arrow.rename_columns(names)
    if "traj_id" in names:
        i = names.index("traj_id")
        ids = pa.array(["" if v is None else str(v) for v in arrow.column(i).to_pylist()], pa.string())
        arrow = arrow.set_column(i, "traj_id", ids)
    return Path("DataFrame"), arrow


def _open(
    path: str | os.PathLike[str] | Any, kind: str, required: tuple[str, ...], allowed: tuple[str, ...]
) -> tuple[Path, Any, list[str]]:
    """The checked path (or a ``pandas.DataFrame``), its Arrow table and column names; missing
    ``required`` or columns not ``allowed`` are errors."""
    if isinstance(path, str | os.PathLike):
        path = check_input_file(path, kind)
        arrow = _read_arrow(path)
    else:
        path, arrow = _frame_to_arrow(path)
    names = list(arrow.column_names)
    missing = [c for c in required if c not in names]
    if missing:
        raise DataFormatError(f"{path}: missing column(s) {', '.join(missing)} (have {', '.join(names)})")
    unknown = [c for c in names if c not in allowed]
    if unknown:
        raise DataFormatError(
            f"{path}: unknown column(s) {', '.join(unknown)}; the columns are {', '.join(allowed)}"
        )
    return path, arrow, names


def _reject_infinite(path: Path, values: dict[str, np.ndarray], ids: np.ndarray | None) -> None:
    """An infinite value in any column is an error naming its column (trajectory) and row."""
    for name, column in values.items():
        bad = np.flatnonzero(np.isinf(column))
        if bad.size:
            row = int(bad[0])
            where = f", trajectory {ids[row]!r}" if ids is not None else ""
            raise DataFormatError(f"{path}: column {name!r}{where}, row {row + 1}: infinite value")


def _reject_same_times(path: Path, t: np.ndarray, rows: np.ndarray, who: str) -> None:
    """Two of the sorted times ``t`` (table rows ``rows``, counted from 0) equal: an error naming
    both rows, prefixed by ``who``."""
    same = np.flatnonzero(np.diff(t) == 0)
    if same.size:
        r1, r2 = sorted(int(r) + 1 for r in rows[same[0] : same[0] + 2])
        raise DataFormatError(f"{path}: {who}rows {r1} and {r2} have the same time t = {t[same[0]]:g} s")


def _trajectory_ids(column: Any) -> tuple[np.ndarray, np.ndarray]:
    """Each row's trajectory id as text (``""`` where missing), an object array, and its rank in
    the ids' text order (an integer array to sort by): through Arrow's dictionary encoding, so
    each distinct id is turned into text once, not once per row."""
    import pyarrow.compute as pc

    encoded = pc.dictionary_encode(column).combine_chunks()
    names = np.asarray([*("" if v is None else str(v) for v in encoded.dictionary.to_pylist()), ""], object)
    indices = encoded.indices
    if indices.null_count:
        indices = indices.fill_null(len(names) - 1)
    codes = indices.to_numpy(zero_copy_only=False).astype(np.int64)
    rank = np.empty(len(names), dtype=np.int64)
    rank[np.argsort(names.astype(str), kind="stable")] = np.arange(len(names))
    return names[codes], rank[codes]


def read_table(path: str | os.PathLike[str] | Any, origin: str | None = None) -> Table:
    """Read and check a trajectory table (see the module docstring): a .csv or .parquet path, or
    a ``pandas.DataFrame`` with the same columns; date-times count in seconds from ``origin``
    where given (a date-time as :attr:`Table.time_origin` holds one), else from the table's
    earliest."""
    path, arrow, names = _open(path, "a table", REQUIRED, COLUMNS)
    for a, b in OPTIONAL_PAIRS:
        if (a in names) != (b in names):
            raise DataFormatError(
                f"{path}: column {a if a not in names else b!r} is missing: give {a} and {b}, or neither"
            )
    rows = arrow.num_rows
    if rows == 0:
        raise DataFormatError(f"{path}: the table has no rows")
    ids, rank = _trajectory_ids(arrow.column("traj_id"))
    times, origin = _times(path, arrow.column("t"), origin)
    values = {c: times if c == "t" else _numeric(path, c, arrow.column(c)) for c in names if c != "traj_id"}
    _reject_infinite(path, values, ids)
    gap = np.zeros(rows, dtype=bool)
    for column in values.values():
        gap |= np.isnan(column)
    gap |= ids == ""
    keep = np.flatnonzero(~gap)
    if keep.size == 0:
        raise DataFormatError(f"{path}: every row has a missing value")
    order = keep[np.lexsort((values["t"][keep], rank[keep]))]  # by id (as text), then time
    sorted_rank = rank[order]
    starts = np.flatnonzero(np.r_[True, sorted_rank[1:] != sorted_rank[:-1]])
    ends = np.r_[starts[1:], order.size]
    trajectories = []
    for a, b in zip(starts, ends, strict=True):
        rows_of = order[a:b]
        traj_id = str(ids[order[a]])
        t = values["t"][rows_of]
        _reject_same_times(path, t, rows_of, f"trajectory {traj_id!r}: ")
        if t.size < MIN_SAMPLES:
            raise DataFormatError(
                f"{path}: trajectory {traj_id!r} has {t.size} sample(s) (row {int(rows_of[0]) + 1}); "
                f"at least {MIN_SAMPLES} are needed"
            )
        pos, vel, force = (_pair(values, a_, b_, rows_of) for a_, b_ in (("x", "y"), *OPTIONAL_PAIRS))
        trajectories.append(Trajectory(traj_id, t, pos, vel, force))
    return Table(trajectories=trajectories, rows=rows, dropped=int(gap.sum()), time_origin=origin)


FORCING_COLUMNS = ("t", "Fx", "Fy")


def read_forcing(
    path: str | os.PathLike[str] | Any, origin: str | None = None
) -> dict[str | None, tuple[np.ndarray, np.ndarray]]:
    """A table of known forces: columns ``t, Fx, Fy`` [s, N, N] and optionally ``traj_id``; ``t``
    in seconds or as ISO-8601 date-times, counted from ``origin`` where given, as in
    :func:`read_table`. Returns ``{traj_id: (t (n,), force (n, 2))}`` sorted by time, with the
    key ``None`` for a table without ``traj_id`` (one forcing for every trajectory). Rows with a
    missing value are dropped; a trajectory needs two rows and distinct times."""
    path, arrow, names = _open(path, "a forcing table", FORCING_COLUMNS, (*FORCING_COLUMNS, "traj_id"))
    if arrow.num_rows == 0:
        raise DataFormatError(f"{path}: the table has no rows")
    values = {c: _numeric(path, c, arrow.column(c)) for c in FORCING_COLUMNS[1:]}
    values["t"] = _times(path, arrow.column("t"), origin)[0]
    _reject_infinite(path, values, None)
    if "traj_id" in names:
        ids = np.asarray([("" if v is None else str(v)) for v in arrow.column("traj_id").to_pylist()])
    else:
        ids = np.full(arrow.num_rows, "all")
    keep = ~np.isnan(values["t"]) & ~np.isnan(values["Fx"]) & ~np.isnan(values["Fy"]) & (ids != "")
    out: dict[str | None, tuple[np.ndarray, np.ndarray]] = {}
    for traj in sorted(set(ids[keep].tolist())):
        rows = np.flatnonzero(keep & (ids == traj))
        rows = rows[np.argsort(values["t"][rows], kind="stable")]
        key = traj if "traj_id" in names else None
        t = values["t"][rows]
        name = "the table" if key is None else f"trajectory {key!r}"
        if t.size < 2:
            raise DataFormatError(f"{path}: {name} has {t.size} row(s) with values; at least 2 are needed")
        _reject_same_times(path, t, rows, "" if key is None else f"{name}: ")
        out[key] = (t, np.stack([values["Fx"][rows], values["Fy"][rows]], axis=1))
    if not out:
        raise DataFormatError(f"{path}: every row has a missing value")
    return out


@dataclasses.dataclass(frozen=True)
class ImportSettings:
    """What the table does not say: the body's known constants and how to split.

    Attributes:
        mass: dry mass ``M`` [kg]. area: reference area ``A`` [m²]. rho: fluid density [kg/m³].
        volume: displaced volume ``V`` [m³] (default ``M / rho``, a floating body).
        split: fractions of the trajectories for train, val and test (summing to 1, each > 0:
            every split gets at least one trajectory).
        seed: seed of the split's permutation.
        time_dependent: whether models may let the flow depend on time.
        smoother: the velocity estimator: a key of :data:`~fhnn.data.derivatives.SMOOTHERS`, or
            ``"auto"`` (the spline up to :data:`~fhnn.data.derivatives.AUTO_SPLINE_ROWS` rows,
            the Kalman smoother above; :func:`~fhnn.data.derivatives.choose_smoother`).
        max_gap: a track is split into pieces where two samples are more than this many seconds
            apart (``inf``: never); ``None``: where they are more than :data:`GAP_STEPS` times
            the track's median step apart (:func:`split_at_gaps`).
        outlier_sigmas: a position more than this many noise levels from the cubic through its
            neighbours is dropped as a glitch (:func:`drop_outliers`); ``None``: every sample kept.
    """

    mass: float
    area: float
    rho: float = 1000.0
    volume: float | None = None
    split: tuple[float, float, float] = (0.7, 0.2, 0.1)
    seed: int = 0
    time_dependent: bool = False
    smoother: str = AUTO
    max_gap: float | None = None
    outlier_sigmas: float | None = OUTLIER_SIGMAS

    def __post_init__(self) -> None:
        choose_smoother(self.smoother, 0)  # an unknown name is refused here
        if self.outlier_sigmas is not None and not (self.outlier_sigmas > 0):
            raise ConfigError(f"--outliers must be a number > 0 (or off), got {self.outlier_sigmas!r}")
        if self.max_gap is not None and not (self.max_gap > 0):
            raise ConfigError(f"--max-gap must be a number of seconds > 0 (or auto), got {self.max_gap!r}")
        for name in ("mass", "area", "rho"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"--{name} must be a number > 0, got {value!r}")
        if self.volume is not None and not (np.isfinite(self.volume) and self.volume > 0):
            raise ConfigError(f"--volume must be a number > 0, got {self.volume!r}")
        if (
            len(self.split) != 3
            or any(not (f >= 0) for f in self.split)
            or not np.isclose(sum(self.split), 1)
        ):
            raise ConfigError(
                f"--split must be three fractions summing to 1 (e.g. 70/20/10), got {self.split}"
            )
        if min(self.split) == 0:  # split_counts would give the split one trajectory regardless
            raise ConfigError(
                f"--split must give train, val and test each a share > 0 (each gets at least one "
                f"trajectory), got {self.split}"
            )
        if self.seed < 0:
            raise ConfigError(f"--seed must be >= 0, got {self.seed}")


def parse_split(text: str) -> tuple[float, float, float]:
    """``"70/20/10"`` → ``(0.7, 0.2, 0.1)``; the parts are percentages summing to 100."""
    parts = text.split("/")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or any(not (v >= 0) for v in values) or not np.isclose(sum(values), 100):
        raise ConfigError(f"--split must be three percentages summing to 100, like 70/20/10; got {text!r}")
    return (values[0] / 100, values[1] / 100, values[2] / 100)


def _positive_or_word(text: str, option: str, word: str, unit: str) -> float | None:
    """``word`` → ``None``; otherwise a number > 0 (``option``'s value, in ``unit``), or a
    :class:`~fhnn.errors.ConfigError` naming the option."""
    if text.strip().lower() == word:
        return None
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise ConfigError(f"{option} must be {word} or a number of {unit} > 0, got {text!r}")
    return value


def parse_max_gap(text: str) -> float | None:
    """``"auto"`` → ``None``; otherwise a number of seconds > 0 (``inf``: never split)."""
    return _positive_or_word(text, "--max-gap", "auto", "seconds")


def parse_outliers(text: str) -> float | None:
    """``"off"`` → ``None``; otherwise a number of noise levels > 0."""
    return _positive_or_word(text, "--outliers", "off", "noise levels")


def _residual_sigmas(t: np.ndarray, pos: np.ndarray, noise: float) -> np.ndarray:
    """``(n − 4,)``: for each interior sample of a track (times ``t`` ``(n,)``, positions
    ``pos`` ``(n, 2)``), the larger of its x and y residuals from the cubic through its two
    neighbours either side, in noise levels ``noise`` [m]."""
    return np.maximum(*(np.abs(lagrange_residuals(t, pos[:, k])) for k in range(2))) / noise


def drop_outliers(pieces: list[Trajectory], noise: float, sigmas: float) -> tuple[list[Trajectory], int, int]:
    """Drop the glitches of a tracker: samples whose position lies more than ``sigmas`` times the
    noise level ``noise`` [m] from the cubic through their two neighbours on either side
    (:func:`~fhnn.data.derivatives.lagrange_residuals`, in x or in y). A glitch also pulls its
    neighbours' residuals (by up to 2/3 of its own), and one among a track's first or last two
    samples shows only in its neighbours', so for each run of flagged samples within 4 of each
    other the sample dropped is the one (of the run and two either side) whose removal leaves the
    least sum of squared residuals around it (a sum, not the largest: with two glitches in a run
    the other one's residual would tie every candidate); passes repeat (at most
    :data:`OUTLIER_PASSES`) until no sample is flagged. Returns ``(pieces, samples dropped, pieces
    with a drop)``; with ``noise`` 0 nothing can be judged and nothing is dropped."""
    if not noise > 0:
        return pieces, 0, 0
    out: list[Trajectory] = []
    dropped = touched = 0
    for tr in pieces:
        keep = np.ones(tr.t.size, dtype=bool)
        for _ in range(OUTLIER_PASSES):
            idx = np.flatnonzero(keep)
            if idx.size < 6:
                break
            t, pos = tr.t[idx], tr.pos[idx]
            flagged = np.flatnonzero(_residual_sigmas(t, pos, noise) > sigmas) + 2  # samples
            if flagged.size == 0:
                break
            for run in np.split(flagged, np.flatnonzero(np.diff(flagged) > 4) + 1):
                lo, hi = max(run[0] - 2, 0), min(run[-1] + 2, idx.size - 1)
                around = np.arange(max(lo - 4, 0), min(hi + 4, idx.size - 1) + 1)
                rests = [around[around != j] for j in range(lo, hi + 1)]
                left = [np.sum(_residual_sigmas(t[r], pos[r], noise) ** 2) for r in rests]
                keep[idx[lo + int(np.argmin(left))]] = False
        if keep.all():
            out.append(tr)
            continue
        dropped += int((~keep).sum())
        touched += 1
        out.append(tr.take(keep))
    return out, dropped, touched


def without_outliers(
    trajectories: list[Trajectory], sigmas: float | None
) -> tuple[list[Trajectory], float, int, int]:
    """:func:`drop_outliers` at the noise level the trajectories' own positions show (``sigmas``
    None: none dropped): ``(trajectories, noise level of what is kept [m], samples dropped,
    trajectories with a drop)``. What ``fhnn import`` does to a table and ``fhnn predict`` to a
    ``--history``."""
    noise = noise_level(_position_series(trajectories))
    if sigmas is None:
        return trajectories, noise, 0, 0
    kept, dropped, touched = drop_outliers(trajectories, noise, sigmas)
    if dropped:
        noise = noise_level(_position_series(kept))
    return kept, noise, dropped, touched


def drop_table_outliers(table: Table, sigmas: float | None) -> tuple[Table, int]:
    """``table`` without its glitches (:func:`without_outliers`; ``sigmas`` None: unchanged) and
    how many positions went: what ``fhnn predict`` does to a ``--history`` before fitting start
    states to it."""
    if sigmas is None:
        return table, 0
    kept, _, dropped, _ = without_outliers(table.trajectories, sigmas)
    return dataclasses.replace(table, trajectories=kept), dropped


@dataclasses.dataclass(frozen=True)
class GapSplit:
    """A table's tracks after :func:`split_at_gaps`: the ``pieces``, the index of the track each
    came from (``track`` ``(P,)``), how many gaps were cut in how many tracks, and how many pieces
    (and rows) were dropped for having fewer than :data:`MIN_SAMPLES` samples."""

    pieces: list[Trajectory]
    track: np.ndarray
    gaps: int
    split_tracks: int
    short_pieces: int
    short_rows: int


def split_at_gaps(trajectories: list[Trajectory], max_gap: float | None) -> GapSplit:
    """Split each track where two consecutive samples are more than ``max_gap`` seconds apart
    (``None``: more than :data:`GAP_STEPS` times the track's median step). Training integrates one
    RK4 step per interval, and a smoother's velocity across a long gap is a guess: a track with a
    tracking outage becomes pieces, each a trajectory of its own. A split track's pieces are named
    ``ID#1``, ``ID#2``, … in time order; a piece with fewer than :data:`MIN_SAMPLES` samples is
    dropped (and counted)."""
    pieces: list[Trajectory] = []
    track: list[int] = []
    gaps = split_tracks = short_pieces = short_rows = 0
    for k, tr in enumerate(trajectories):
        steps = np.diff(tr.t)
        limit = GAP_STEPS * float(np.median(steps)) if max_gap is None else max_gap
        cuts = np.flatnonzero(steps > limit) + 1
        if cuts.size == 0:
            pieces.append(tr)
            track.append(k)
            continue
        gaps += int(cuts.size)
        split_tracks += 1
        bounds = np.r_[0, cuts, tr.t.size]
        for j, (a, b) in enumerate(itertools.pairwise(bounds)):
            if b - a < MIN_SAMPLES:
                short_pieces += 1
                short_rows += int(b - a)
                continue
            pieces.append(tr.take(slice(a, b), f"{tr.traj_id}#{j + 1}"))
            track.append(k)
    return GapSplit(pieces, np.asarray(track, dtype=np.int64), gaps, split_tracks, short_pieces, short_rows)


def split_counts(n: int, fractions: tuple[float, float, float]) -> tuple[int, int, int]:
    """Trajectories per split: at least one each, the rest by ``fractions`` (largest remainders)."""
    if n < 3:
        raise DataFormatError(f"the table has {n} trajectory(ies); train, val and test need at least 3")
    exact = np.asarray(fractions) * n
    counts = np.maximum(np.floor(exact).astype(int), 1)
    while counts.sum() > n:
        counts[int(np.argmax(counts))] -= 1
    order = np.argsort(-(exact - np.floor(exact)), kind="stable")
    i = 0
    while counts.sum() < n:
        counts[order[i % 3]] += 1
        i += 1
    return int(counts[0]), int(counts[1]), int(counts[2])


def _pad(a: np.ndarray, size: int) -> np.ndarray:
    """``a`` ``(n, ...)`` extended to ``size`` rows by repeating its last row."""
    return np.concatenate([a, np.repeat(a[-1:], size - a.shape[0], axis=0)], axis=0)


def _split_of(items: list[dict[str, np.ndarray]]) -> Split:
    size = max(item["t"].size for item in items)
    t = np.stack(
        [
            np.r_[item["t"], item["t"][-1] + PAD_STEP * np.arange(1, size - item["t"].size + 1)]
            for item in items
        ]
    )
    stack = lambda key: np.stack([_pad(item[key], size) for item in items])  # noqa: E731
    states = stack("states")
    derivs = stack("derivs")
    for i, item in enumerate(items):  # padding has no motion
        derivs[i, item["t"].size :] = 0.0
    lengths = np.asarray([item["t"].size for item in items], dtype=np.int64)
    return Split(
        t=t,
        states=states,
        states_clean=states.copy(),
        derivs=derivs,
        forces=stack("forces"),
        actuation=np.zeros((len(items), 2, 3, 3)),
        lengths=lengths,
    )


def table_to_dataset(table: Table, settings: ImportSettings, source: str = "") -> Dataset:
    """A data set of ``table``'s trajectories (see the module docstring).

    Times are shifted so that the earliest sample of the table is at ``t = 0`` (the shift is kept
    in the ``import`` record); ``states_clean`` holds the observed states (the truth is unknown),
    ``derivs`` the estimated ``(vx, vy, ax, ay)``.
    """
    cut = split_at_gaps(table.trajectories, settings.max_gap)
    trajs = cut.pieces
    kept = int(np.unique(cut.track).size)
    if kept < 3:
        split_counts(len(table.trajectories), settings.split)  # too few tracks in the table: refused there
        raise DataFormatError(
            f"{kept} of the table's {len(table.trajectories)} trajectories keep a piece of at least "
            f"{MIN_SAMPLES} samples between gaps longer than --max-gap; train, val and test need at least 3"
        )
    has_vel = trajs[0].vel is not None
    has_force = trajs[0].force is not None
    t0 = min(float(tr.t[0]) for tr in trajs)
    trajs, pos_noise, outliers, touched = without_outliers(trajs, settings.outlier_sigmas)
    series = _position_series(trajs)
    smoother = choose_smoother(settings.smoother, table.rows)
    vel_noise = vel_error = None
    if has_vel:  # the acceleration of each measured velocity
        velocities = [(tr.t, tr.vel[:, k]) for tr in trajs for k in range(2)]
        vel_noise = noise_level(velocities)
        rates = smooth_derivatives(velocities, vel_noise, smoother)
    else:  # (velocity, acceleration) of each position
        rates = smooth_derivatives(series, pos_noise, smoother)
        vel_error = derivative_error(series, pos_noise, smoother, seed=settings.seed)
    items = []
    for i, tr in enumerate(trajs):
        vel = np.empty_like(tr.pos)
        acc = np.empty_like(tr.pos)
        for k in range(2):
            first, second = rates[2 * i + k]
            if has_vel:
                vel[:, k], acc[:, k] = tr.vel[:, k], first
            else:
                vel[:, k], acc[:, k] = first, second
        items.append(
            {
                "t": tr.t - t0,
                "states": np.concatenate([tr.pos, vel], axis=1),
                "derivs": np.concatenate([vel, acc], axis=1),
                "forces": tr.force if has_force else np.zeros_like(tr.pos),
            }
        )
    bad = [
        tr.traj_id for tr, item in zip(trajs, items, strict=True) if not np.all(np.isfinite(item["derivs"]))
    ]
    if bad:  # never write what the estimator could not give
        raise DataFormatError(
            f"velocity estimates are not finite for trajectory {bad[0]!r} ({len(bad)} in all)"
        )
    # the split permutes the table's tracks: the pieces of a track split at gaps stay together
    tracks = np.unique(cut.track)
    counts = split_counts(tracks.size, settings.split)
    perm = tracks[np.random.default_rng(settings.seed).permutation(tracks.size)]
    bounds = np.cumsum((0, *counts))
    members = {
        name: np.flatnonzero(np.isin(cut.track, perm[bounds[k] : bounds[k + 1]]))
        for k, name in enumerate(SPLITS)
    }
    splits = {name: _split_of([items[i] for i in members[name]]) for name in SPLITS}
    steps = np.concatenate([np.diff(tr.t) for tr in trajs])
    measured = ["positions", *(["velocities"] if has_vel else []), *(["forces"] if has_force else [])]
    volume = settings.volume if settings.volume is not None else settings.mass / settings.rho
    ids = {name: [trajs[i].traj_id for i in members[name]] for name in SPLITS}
    record = {
        "source": source,
        "rows": table.rows,
        "dropped_rows": table.dropped,
        "trajectories": len(trajs),
        "tracks": len(table.trajectories),
        "max_gap": settings.max_gap,
        "gap_steps": GAP_STEPS if settings.max_gap is None else None,
        "gaps_split": cut.gaps,
        "tracks_split": cut.split_tracks,
        "short_pieces_dropped": cut.short_pieces,
        "short_piece_rows": cut.short_rows,
        "outlier_sigmas": settings.outlier_sigmas,
        "outliers_dropped": outliers,
        "outlier_trajectories": touched,
        "time_offset": t0,
        "time_origin": table.time_origin,
        "position_noise": pos_noise,
        "velocity_noise": vel_noise,
        "velocity_error": vel_error,
        "velocity": "measured" if has_vel else f"{smoother} smoother at the noise level (RMS residual = σ)",
        "smoother": smoother,
        "step_median": float(np.median(steps)),
        "step_range": [float(steps.min()), float(steps.max())],
        "traj_ids": ids,
    }
    return Dataset(
        scenario=IMPORTED,
        scenario_params={"time_dependent": bool(settings.time_dependent)},
        body_params={"M": settings.mass, "rho": settings.rho, "A": settings.area, "V": volume},
        seed=int(settings.seed),
        dt=float(np.median(steps)),
        actuation="recorded" if has_force else "none",
        obs_noise=float(pos_noise),
        version=__version__,
        splits=splits,
        extra={"measured": measured, "import": record},
    )


def start_errors(dataset: Dataset) -> tuple[float, float]:
    """``(σ_x [m], σ_v [m/s])``: the noise of ``dataset``'s observed positions and the RMS error of
    its estimated velocities, which a multi-step training window starts from. From the import
    record (``position_noise``, ``velocity_error``), estimated from the positions of every split
    where the record lacks them (a file imported before the record kept the velocity error, or a
    data set without an import record: the spline smoother assumed)."""
    record = dataset.extra.get("import") or {}
    noise, error = record.get("position_noise"), record.get("velocity_error")
    if noise is not None and error is not None:
        return float(noise), float(error)
    series = []
    for name in SPLITS:
        split = dataset[name]
        for i, k in enumerate(split.sample_counts):
            series += [(split.times[i, :k], split.states[i, :k, a]) for a in range(2)]
    if noise is None:
        noise = noise_level(series)
    smoother = record.get("smoother") or "spline"
    return float(noise), derivative_error(series, float(noise), smoother, seed=dataset.seed)


def observe(
    dataset: Dataset,
    *,
    step: float,
    jitter: float = 0.0,
    noise: float = 0.0,
    drop: float = 0.0,
    velocities: bool = False,
    forces: bool = True,
    seed: int = 0,
) -> dict[str, np.ndarray]:
    """A table (columns by name, one row per sample, rows shuffled) of what an instrument would
    record of a simulated, finely sampled ``dataset``: every trajectory of every split, sampled
    about every ``step`` s with each interval drawn from ``step·U(1 − jitter, 1 + jitter)`` (the
    nearest stored sample is taken, so the data set's ``dt`` must be much finer than ``step``),
    positions (and velocities when ``velocities``) with Gaussian noise of std ``noise`` [m, m/s],
    the known forces when ``forces``, and a fraction ``drop`` of the rows replaced by gaps (NaN
    positions). The worked example and ``benchmarks/own_data.py`` make their tables so."""
    rng = np.random.default_rng(seed)
    columns: dict[str, list[np.ndarray]] = {c: [] for c in ("traj_id", "t", "x", "y", "vx", "vy", "Fx", "Fy")}
    k = 0
    for name in SPLITS:
        split = dataset[name]
        if not split.regular:
            raise ConfigError("observe() needs a simulated data set (common sample times)")
        t = split.t
        for i in range(split.n_traj):
            draws = step * rng.uniform(1 - jitter, 1 + jitter, int(2 * t[-1] / step) + 2)
            wanted = np.concatenate([[0.0], np.cumsum(draws)])
            idx = np.unique(np.searchsorted(t, wanted[wanted <= t[-1]]).clip(0, t.size - 1))
            clean = split.states_clean[i, idx]
            columns["traj_id"].append(np.full(idx.size, k))
            columns["t"].append(t[idx])
            for j, c in enumerate(("x", "y", "vx", "vy")):
                columns[c].append(clean[:, j] + noise * rng.normal(size=idx.size))
            columns["Fx"].append(split.forces[i, idx, 0])
            columns["Fy"].append(split.forces[i, idx, 1])
            k += 1
    table = {c: np.concatenate(v) for c, v in columns.items()}
    gaps = rng.random(table["t"].size) < drop
    table["x"][gaps] = np.nan
    table["y"][gaps] = np.nan
    keep = [c for c in COLUMNS if (velocities or c not in ("vx", "vy")) and (forces or c not in ("Fx", "Fy"))]
    order = rng.permutation(table["t"].size)
    return {c: table[c][order] for c in keep}


def check_table_name(path: str | os.PathLike[str]) -> Path:
    """``path`` as a :class:`Path` if it names a ``.csv`` or ``.parquet`` file; else ConfigError."""
    path = Path(path)
    if path.suffix.lower() not in (".csv", ".parquet"):
        raise ConfigError(f"{path}: give a .csv or .parquet file name")
    return path


def write_table(columns: dict[str, np.ndarray], path: str | os.PathLike[str]) -> Path:
    """Write a table of named columns as ``.csv`` or ``.parquet`` (by the suffix), atomically."""
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    path = check_table_name(path)
    arrow = pa.table({name: pa.array(values) for name, values in columns.items()})
    with atomic_output(path) as tmp:
        if path.suffix.lower() == ".csv":
            pacsv.write_csv(arrow, tmp)
        else:
            pq.write_table(arrow, tmp)
    return path


__all__ = [
    "COLUMNS",
    "SECONDS_ONLY",
    "ImportSettings",
    "Table",
    "Trajectory",
    "check_table_name",
    "dataset_clock",
    "observe",
    "parse_split",
    "read_forcing",
    "read_table",
    "seconds_to_date_times",
    "shift_times",
    "start_errors",
    "table_to_dataset",
    "write_table",
]
