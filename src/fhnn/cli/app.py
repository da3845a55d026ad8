"""``fhnn`` command line: each command parses its options, calls one function of :mod:`fhnn.api`
and prints what it returns. A command imports that function when it runs, so the command line
starts without the API's own dependencies (``tests/test_cli.py`` checks which modules it loads).

Every error caused by input (a bad option, parameter, file) is printed as one line
``error: <what is wrong>`` on standard error, with exit status 2 and no partial output.
"""

from __future__ import annotations

import signal
import sys

import typer

from fhnn.api.report import FAULT_ENV
from fhnn.cli.options import app
from fhnn.cli.render import err
from fhnn.errors import FhnnError, Interrupted

# the commands register themselves on import, in the order --help lists them
# isort: off
from fhnn.cli import data  # noqa: F401
from fhnn.cli import train  # noqa: F401
from fhnn.cli import evaluate  # noqa: F401
from fhnn.cli import inspect  # noqa: F401
from fhnn.cli import reproduce  # noqa: F401
from fhnn.cli import turning  # noqa: F401

# isort: on

# Typer >= 0.29 vendors its own click; older releases raise click's exceptions.
_USAGE_ERRORS: tuple[type[Exception], ...] = (typer.TyperException,)
try:
    import click

    _USAGE_ERRORS += (click.exceptions.ClickException,)
except ImportError:  # pragma: no cover - depends on the Typer release
    pass

__all__ = ["FAULT_ENV", "app", "main"]


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``fhnn`` console script."""
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a kill stops cleanly, like Ctrl-C
    try:
        code = app(args=argv, prog_name="fhnn", standalone_mode=False)
    except Interrupted as exc:  # train and reproduce say what they kept
        err.print(str(exc), highlight=False, markup=False, soft_wrap=True)
        sys.exit(130)
    except typer.Abort:
        _fail("aborted")
    except _USAGE_ERRORS as exc:
        _fail(exc.format_message() if hasattr(exc, "format_message") else str(exc))
    except FhnnError as exc:
        _fail(str(exc))
    except OSError as exc:
        _fail(f"{exc.strerror or exc}: {exc.filename}" if exc.filename else str(exc))
    if code == 130:  # Typer's answer to Ctrl-C (SIGINT, or SIGTERM below) in any other command
        err.print("interrupted: files are written whole or not at all", highlight=False)
    sys.exit(code if isinstance(code, int) else 0)


def _fail(message: str) -> None:
    err.print(f"error: {' '.join(message.split())}", highlight=False, markup=False, soft_wrap=True)
    sys.exit(2)


if __name__ == "__main__":
    main()
