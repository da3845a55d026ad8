"""``fhnn inspect``."""

from __future__ import annotations

import json
from typing import Annotated

import typer

from fhnn.cli import render
from fhnn.cli.options import DataArgument, RunDirArgument, app


@app.command()
def inspect(
    run_dir: RunDirArgument,
    data: DataArgument = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the recovery numbers as JSON.")] = False,
) -> None:
    """Learned coefficients against the truth, flow recovery, and figures (PNG) written into RUN,
    with the learned coefficients over the covered (r, σ) as coefficients.csv and the learned flow
    on a grid as flow.nc (NetCDF-4). On imported data (no truth): the learned coefficients over
    the region the data cover, and the learned flow. A single run's coefficients come with 90 %
    intervals from the whole-track fit's curvature and a note on what the data do not determine
    (intervals withheld or marked weak). On an ensemble (fhnn train --seeds N): every
    coefficient and identifiable ratio with the members' median and 90 % interval (and whether it
    covers the truth), coefficients.csv with NAME_lo/NAME_hi columns and flow.nc with u_lo, u_hi, …"""
    from fhnn.api.inspect import inspect as inspect_fit

    result = inspect_fit(run_dir, data)
    for text in result.notes:
        render.note(text)
    if as_json:
        typer.echo(json.dumps(result.json(), indent=2))
        return
    render.sections(result.sections)
