"""``fhnn reproduce``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from fhnn.cli import render
from fhnn.cli.options import ConfigFileOption, QuietOption, SetOption, app
from fhnn.experiments.grid import JOB_ADAM_STEPS, JOB_LBFGS_PAIRS, JOB_SECONDS
from fhnn.training.plans import DEFAULT_PLAN, PLANS
from fhnn.training.settings import parse_params


@app.command()
def reproduce(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Output folder (created; resumed if it exists).")
    ] = Path("reproduction"),
    quick: Annotated[
        bool,
        typer.Option(
            "--quick",
            help=(
                "Small data, few steps, one seed, one main scenario, jobs compiled for compilation "
                "speed (fast_compile): the whole report in minutes."
            ),
        ),
    ] = False,
    seeds: Annotated[int | None, typer.Option(help="Seeds per model [default: 3; --quick: 1].")] = None,
    steps: Annotated[
        int | None,
        typer.Option(
            help=f"Adam steps per model [default: {JOB_ADAM_STEPS}, with the default plan's warm-up, "
            f"loss and polish of up to {PLANS[DEFAULT_PLAN].train.lbfgs_steps} L-BFGS iterations (on "
            f"{JOB_LBFGS_PAIRS} pairs) and {JOB_SECONDS:g} s per job (train.max_time); --quick: 80, "
            "Adam only]."
        ),
    ] = None,
    workers: Annotated[
        int | None, typer.Option(help="Local worker processes [default: one per CPU core].")
    ] = None,
    ray: Annotated[
        str | None,
        typer.Option(
            "--ray",
            help="Run the jobs on a Ray cluster: its ADDRESS, 'auto' (the running cluster) or 'local' "
            "(start one here). Needs pip install 'fhnn[ray]'.",
        ),
    ] = None,
    config_file: ConfigFileOption = None,
    set_: SetOption("models=fhnn,node, data.n_traj=50, train.lbfgs_steps=200, model.fhnn.width=32") = None,
    quiet: QuietOption = False,
) -> None:
    """Regenerate the data, train every model/ablation/scenario/seed of the paper's tables, evaluate,
    and write tables (Markdown, CSV, JSON), figures (PNG, SVG), report.md and index.html into OUT.
    Finished jobs are kept: an interrupted run resumes, an unchanged one does nothing."""
    from fhnn.api.reproduce import reproduce as reproduce_paper

    summary = reproduce_paper(
        out,
        quick=quick,
        seeds=seeds,
        steps=steps,
        workers=workers,
        ray=ray,
        settings=parse_params(set_ or []),
        config_file=config_file,
        progress=not quiet,
    )
    ran = (
        f"{summary.data_run} of {summary.data_total} data sets and "
        f"{summary.jobs_run} of {summary.jobs_total} training jobs run"
    )
    built = "report rebuilt" if summary.report_built else "nothing changed, report kept"
    render.stdout.print(f"{ran}, {built} in {summary.seconds:.0f} s: {out / 'index.html'}")
