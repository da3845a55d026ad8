"""Exceptions raised for bad input.

Every error a user can cause — a bad configuration value, a malformed file or table, an impossible
request — is an :class:`FhnnError`. Its message is one line that names the offending value; the CLI
prints it as ``error: <message>`` and exits with status 2.
"""


class FhnnError(Exception):
    """Base class of every error caused by user input."""


class ConfigError(FhnnError, ValueError):
    """A configuration value is unknown, of the wrong type or out of range."""


class DataFormatError(FhnnError, ValueError):
    """A data file or table is missing, truncated, foreign or inconsistent."""


class SimulationError(FhnnError, RuntimeError):
    """The ground-truth simulator could not produce the requested trajectories."""


class Interrupted(Exception):
    """Ctrl-C or SIGTERM stopped work that is kept (training, a reproduction); the message says
    what was kept and how to resume (the CLI exits with status 130)."""
