"""A user's observed trajectories, from a CSV or Parquet table into a data set (``fhnn import``).

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

Rows with a missing value (an empty cell or NaN) in any column present are gaps, dropped and
counted; outages and glitches are handled by :mod:`fhnn.data.cleaning`. Any other problem — a
missing or unknown column, a non-numeric or infinite value, two rows of one trajectory at the same
time, a trajectory with fewer than :data:`MIN_SAMPLES` samples — is a
:class:`~fhnn.errors.DataFormatError` naming the column, the trajectory and the row (data rows
counted from 1). Known forces may instead come as a table of their own (:func:`read_forcing`).
What the table lacks is estimated (:mod:`fhnn.data.derivatives`) when it becomes a data set
(:mod:`fhnn.data.conversion`).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fhnn.data.clock import DATE, SECONDS_ONLY, ZONE, date_time, origin_ns
from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import atomic_output, check_input_file
from fhnn.physics.actuation import held_grid

REQUIRED = ("traj_id", "t", "x", "y")
OPTIONAL_PAIRS = (("vx", "vy"), ("Fx", "Fy"))
COLUMNS = (*REQUIRED, *(c for pair in OPTIONAL_PAIRS for c in pair))
#: Fewest samples a trajectory may have (velocity and noise estimates need neighbours).
MIN_SAMPLES = 3
#: Padding after a shorter trajectory's last sample: times go on in steps of this [s].
PAD_STEP = 1e-6


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


def position_series(trajectories: list[Trajectory]) -> list[tuple[np.ndarray, np.ndarray]]:
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
        pc.match_substring_regex(column, DATE)
    ).as_py():
        text = pc.if_else(pc.equal(pc.utf8_trim_whitespace(column), ""), pa.scalar(None, column.type), column)
        text = text.combine_chunks() if hasattr(text, "combine_chunks") else text
        zoned = np.asarray(pc.match_substring_regex(text, ZONE).to_numpy(zero_copy_only=False), dtype=object)
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
        start = origin_ns(origin)
    else:
        start = int(values[valid].min()) if valid.any() else 0
    seconds = np.where(valid, (values - start) / 1e9, np.nan)
    return seconds, origin if origin is not None else date_time(start, zone)


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


def shift_times(table: Table, seconds: float) -> Table:
    """``table`` with every sample time moved by ``seconds``."""
    moved = [dataclasses.replace(tr, t=tr.t + seconds) for tr in table.trajectories]
    return dataclasses.replace(table, trajectories=moved)


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
    return Path("DataFrame"), arrow.rename_columns(names)


def _ids_as_text(arrow: Any) -> Any:
    """``arrow`` with its ``traj_id`` column as text (a DataFrame's may hold numbers)."""
    import pyarrow as pa

    i = arrow.column_names.index("traj_id")
    ids = pa.array(["" if v is None else str(v) for v in arrow.column(i).to_pylist()], pa.string())
    return arrow.set_column(i, "traj_id", ids)


#: The units numeric times may be given in (``--time-unit``), in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0}


def time_unit_seconds(unit: str) -> float:
    """Seconds in one ``unit`` of :data:`TIME_UNITS`; an unknown unit is a ConfigError."""
    if unit not in TIME_UNITS:
        raise ConfigError(f"--time-unit must be one of {', '.join(TIME_UNITS)}, got {unit!r}")
    return TIME_UNITS[unit]


def parse_columns(text: str | Mapping[str, str] | None) -> dict[str, str]:
    """A column mapping: ``"traj_id=track,t=time,x=pos_x"`` (or a mapping) → ``{our name: the
    table's name}``; ``None`` or ``""``: none.

    Raises:
        ConfigError: an item without ``=``, a name that is not one of :data:`COLUMNS`, or a name
            or a table column mapped twice.
    """
    if not text:
        return {}
    if isinstance(text, Mapping):
        items = [(str(k).strip(), str(v).strip()) for k, v in text.items()]
    else:
        items = []
        for item in text.split(","):
            ours, sep, theirs = item.partition("=")
            if not sep or not ours.strip() or not theirs.strip():
                raise ConfigError(f"--columns expects NAME=COLUMN[,NAME=COLUMN...], got {item.strip()!r}")
            items.append((ours.strip(), theirs.strip()))
    out: dict[str, str] = {}
    for ours, theirs in items:
        if ours not in COLUMNS:
            raise ConfigError(f"--columns: {ours!r} is not a column of fhnn's; they are {', '.join(COLUMNS)}")
        if ours in out:
            raise ConfigError(f"--columns: {ours} is mapped twice")
        if theirs in out.values():
            raise ConfigError(f"--columns: the table's column {theirs!r} is mapped twice")
        out[ours] = theirs
    return out


def _rename(path: Path, arrow: Any, columns: Mapping[str, str]) -> Any:
    """``arrow`` with the table's columns renamed to ours by ``columns`` (ours → theirs)."""
    names = list(arrow.column_names)
    missing = [f"{theirs!r} (for {ours})" for ours, theirs in columns.items() if theirs not in names]
    if missing:
        raise DataFormatError(f"{path}: no column {', '.join(missing)} (have {', '.join(names)})")
    back = {theirs: ours for ours, theirs in columns.items()}
    clash = [n for n in names if n in columns and n not in back]
    if clash:
        raise DataFormatError(
            f"{path}: column(s) {', '.join(clash)} would be replaced by the mapped ones; drop or map them"
        )
    return arrow.rename_columns([back.get(n, n) for n in names])


def _open(
    path: str | os.PathLike[str] | Any,
    kind: str,
    required: tuple[str, ...],
    allowed: tuple[str, ...],
    columns: Mapping[str, str] | None = None,
) -> tuple[Path, Any, list[str]]:
    """The checked path (or a ``pandas.DataFrame``), its Arrow table and column names, the
    table's columns renamed by ``columns`` (ours → theirs); missing ``required`` or columns not
    ``allowed`` are errors."""
    frame = not isinstance(path, str | os.PathLike)
    if frame:
        path, arrow = _frame_to_arrow(path)
    else:
        path = check_input_file(path, kind)
        arrow = _read_arrow(path)
    if columns:
        arrow = _rename(path, arrow, {k: v for k, v in columns.items() if k in allowed})
    if frame and "traj_id" in arrow.column_names:  # a file's ids are read as text by type
        arrow = _ids_as_text(arrow)
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


def read_table(
    path: str | os.PathLike[str] | Any,
    origin: str | None = None,
    columns: Mapping[str, str] | None = None,
    time_unit: str = "s",
) -> Table:
    """Read and check a trajectory table (see the module docstring).

    Args:
        path: a .csv or .parquet path, or a ``pandas.DataFrame`` with the same columns.
        origin: date-times count in seconds from this date-time (as :attr:`Table.time_origin`
            holds one); default: from the table's earliest.
        columns: the table's names of our columns (:func:`parse_columns`), e.g.
            ``{"traj_id": "track", "t": "time"}``; unnamed ones keep their names.
        time_unit: the unit of numeric times (:data:`TIME_UNITS`): they are read as seconds.

    Raises:
        ConfigError: an unknown ``time_unit``, or one other than seconds for date-times.
        DataFormatError: a missing, unreadable or inconsistent table.
    """
    scale = time_unit_seconds(time_unit)
    path, arrow, names = _open(path, "a table", REQUIRED, COLUMNS, columns)
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
    if scale != 1.0:
        if origin is not None:
            raise ConfigError(f"--time-unit {time_unit} applies to numeric times; {path} gives date-times")
        times = times * scale
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
    path: str | os.PathLike[str] | Any,
    origin: str | None = None,
    columns: Mapping[str, str] | None = None,
    time_unit: str = "s",
) -> dict[str | None, tuple[np.ndarray, np.ndarray]]:
    """A table of known forces: columns ``t, Fx, Fy`` [s, N, N] and optionally ``traj_id``; ``t``
    in seconds or as ISO-8601 date-times, counted from ``origin`` where given, as in
    :func:`read_table`. Returns ``{traj_id: (t (n,), force (n, 2))}`` sorted by time, with the
    key ``None`` for a table without ``traj_id`` (one forcing for every trajectory). Rows with a
    missing value are dropped; a trajectory needs two rows and distinct times. ``columns``: the
    table's names of ours and ``time_unit`` the unit of numeric times, as for :func:`read_table`."""
    scale = time_unit_seconds(time_unit)
    path, arrow, names = _open(
        path, "a forcing table", FORCING_COLUMNS, (*FORCING_COLUMNS, "traj_id"), columns
    )
    if arrow.num_rows == 0:
        raise DataFormatError(f"{path}: the table has no rows")
    values = {c: _numeric(path, c, arrow.column(c)) for c in FORCING_COLUMNS[1:]}
    values["t"], dates = _times(path, arrow.column("t"), origin)
    if scale != 1.0:
        if dates is not None:
            raise ConfigError(f"--time-unit {time_unit} applies to numeric times; {path} gives date-times")
        values["t"] = values["t"] * scale
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


#: How a forcing table's forces are read between its rows (``fhnn predict --forcing-hold``).
FORCING_HOLDS = ("linear", "previous")


def held(
    rows: dict[str | None, tuple[np.ndarray, np.ndarray]], hold: str
) -> dict[str | None, tuple[np.ndarray, np.ndarray]]:
    """A forcing table (as :func:`read_forcing` returns it) read as ``hold`` says: ``"linear"``
    between rows (unchanged), or ``"previous"``: each row's force held until the next row, as
    thrusters that switch at the rows' times do. A held table is returned as rows whose linear
    interpolant is that step function (:func:`~fhnn.physics.actuation.held_grid`, each change at
    its row's time: a row :data:`~fhnn.physics.actuation.STEP_WIDTH` s before it holds the
    previous force).

    Raises:
        ConfigError: an unknown ``hold``.
    """
    check_forcing_hold(hold)
    if hold == "linear":
        return rows
    out = {}
    for key, (t, force) in rows.items():
        at_rows = np.r_[t[1:], t[-1]]  # each row's change at the row itself, not between rows
        grid, values, _ = held_grid(t[None], force[None], at_rows[None])
        out[key] = (grid[0], values[0])
    return out


def check_forcing_hold(hold: str) -> str:
    """``hold`` if it is one of :data:`FORCING_HOLDS`; else :class:`ConfigError`."""
    if hold not in FORCING_HOLDS:
        raise ConfigError(f"--forcing-hold must be one of {', '.join(FORCING_HOLDS)}, got {hold!r}")
    return hold


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
