"""Clocks of imported tables: ISO-8601 date-times read as seconds after an origin, and back."""

from __future__ import annotations

from typing import Any

import numpy as np

from fhnn.data.dataset import Dataset

#: The ``origin`` of :func:`read_table` and :func:`read_forcing` for a clock in seconds, with no
#: date-time origin: a table of date-times is then an error.
SECONDS_ONLY = ""

#: A value that starts like an ISO-8601 date, and one that ends with a zone ("Z", "+02:00").
DATE = r"^\s*\d{4}-\d{2}-\d{2}"
ZONE = r"(Z|[+-]\d{2}:?\d{2})\s*$"


def origin_ns(origin: str) -> int:
    """The date-time ``origin`` (as :func:`~fhnn.data.table.read_table` reads it, "Z" for UTC) in
    nanoseconds since 1970."""
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


def seconds_to_date_times(seconds: np.ndarray, origin: str) -> np.ndarray:
    """``seconds`` after the date-time ``origin`` (as :func:`_times` returns it) as ISO-8601 text
    (rounded to the nanosecond), with ``origin``'s zone."""
    ns = origin_ns(origin) + np.round(np.asarray(seconds, dtype=float) * 1e9).astype(np.int64)
    return date_time(ns, "Z" if origin.endswith("Z") else "")
