"""The ``fhnn`` command-line tool (Typer + Rich)."""
