"""Where the library's long functions say what they do: notes and warnings on standard error,
results on standard output, and progress bars (Rich; they render in a terminal and a notebook)."""

from __future__ import annotations

import os
import signal
from typing import Any

from rich.console import Console
from rich.progress import Progress, ProgressColumn

#: Test hook of the fault tests (tests/test_faults.py): ``PHASE:N:SIGNAL`` (e.g. ``adam:40:KILL``)
#: makes the process send itself SIGNAL once its progress reaches N in PHASE — a simulated split
#: ("train", …), a training phase ("warmup", "adam", "lbfgs") or a reproduction's "jobs" /
#: "report" — so a kill lands in a chosen phase. Unset in normal use.
FAULT_ENV = "FHNN_FAULT_AT"


def fault_point(phase: str, done: int) -> None:
    """Send the signal :data:`FAULT_ENV` asks for once ``done`` reaches it in ``phase``."""
    spec = os.environ.get(FAULT_ENV)
    if spec:
        where, at, name = spec.split(":")
        if where == phase and done >= int(at):
            os.kill(os.getpid(), getattr(signal, f"SIG{name}"))


class Reporter:
    """What a function tells its user while it works.

    Args:
        quiet: no notes, results or progress bars; warnings are still said.
    """

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.out = Console()
        self.err = Console(stderr=True)

    def note(self, text: str) -> None:
        """A line on standard error, unless quiet."""
        if not self.quiet:
            self.warn(text)

    def warn(self, text: str) -> None:
        """A line on standard error, even when quiet."""
        self.err.print(text, highlight=False, markup=False, soft_wrap=True)

    def result(self, text: str, *, always: bool = False) -> None:
        """A line on standard output, unless quiet (``always``: even then)."""
        if always or not self.quiet:
            self.out.print(text, highlight=False, markup=False, soft_wrap=True)

    def progress(self, *columns: str | ProgressColumn, **kwargs: Any) -> Progress:
        """A progress display on standard error (disabled when quiet)."""
        return Progress(*columns, console=self.err, disable=self.quiet, **kwargs)


def reporter(value: Reporter | bool | None) -> Reporter:
    """A :class:`Reporter` from a function's ``progress`` argument (``False``: quiet)."""
    if isinstance(value, Reporter):
        return value
    return Reporter(quiet=value is False)


def fmt(x: float) -> str:
    """A number as the reports print it: four significant digits."""
    return f"{x:.4g}"


class TableData:
    """A table of a report: a title, column names and rows of formatted cells.

    Args:
        title: the table's title.
        columns: the column names.
        rows: the rows, each a list of cells (strings).
    """

    def __init__(self, title: str, columns: list[str], rows: list[list[str]]) -> None:
        self.title, self.columns, self.rows = title, columns, rows

    def text(self) -> str:
        """The table as plain text (columns separated by two spaces)."""
        lines = [self.title, "  ".join(self.columns)]
        lines += ["  ".join(row) for row in self.rows]
        return "\n".join(lines)

    def to_pandas(self) -> Any:
        """The table as a ``pandas.DataFrame`` of strings."""
        import pandas as pd

        return pd.DataFrame(self.rows, columns=self.columns)
