"""The ``fhnn`` command-line tool (Typer + Rich)."""

import time

#: When the command's process reached fhnn (``time.monotonic()``), before its heavy imports: a
#: command's time budget (``--max-time``) counts from here.
STARTED = time.monotonic()
