"""``fhnn train``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from fhnn.cli import STARTED
from fhnn.cli.options import ConfigFileOption, QuietOption, SetOption, app
from fhnn.models.registry import MODELS
from fhnn.training.plans import DEFAULT_PLAN, ESTIMATED_VELOCITY_PLAN, PLANS
from fhnn.training.settings import parse_params


@app.command()
def train(
    data: Annotated[Path, typer.Argument(help="Training data set (HDF5).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Run folder to create (or resume).")],
    model: Annotated[str | None, typer.Option(help=f"Model kind: {'|'.join(MODELS)} [default: fhnn]")] = None,
    ablation: Annotated[
        str | None, typer.Option(help=f"FHNN ablation: none|{'|'.join(MODELS['fhnn'].variants)}")
    ] = None,
    plan: Annotated[
        str | None,
        typer.Option(
            help=f"Training plan: {'|'.join(PLANS)} (its training settings and the model settings it "
            f"was chosen with; noisy observations turn the FHNN's slow-window weights off; --set "
            f"wins; see README) "
            f"[default: {DEFAULT_PLAN}; {ESTIMATED_VELOCITY_PLAN} on data with estimated velocities]"
        ),
    ] = None,
    steps: Annotated[
        int | None,
        typer.Option(
            help="Adam steps (train.steps) [default: 20000; 4000 on data with estimated velocities]"
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(
            help="Seed of initialisation and batch order, and of an ensemble member's bootstrap "
            "weights (train.seed) [default: 0]"
        ),
    ] = None,
    max_time: Annotated[
        float | None,
        typer.Option(
            "--max-time",
            help="Wall-clock budget in seconds for the whole command (train.max_time; compilation "
            "and every member of an ensemble included): the phases before an L-BFGS polish or "
            "whole-track fit end at half of it, those at all of it, no step starting that would end "
            "past it; the run says what ran, and the same command again continues it with a new "
            "budget [default: none]",
        ),
    ] = None,
    n_seeds: Annotated[
        int | None,
        typer.Option(
            "--seeds",
            help="Train an ensemble of N runs with seeds --seed … --seed+N−1 into RUN/seed-S, each on "
            "its own Bayesian bootstrap of the training trajectories (each weighted at random; "
            "--set train.bootstrap=false: "
            "all on the same data), their Adam phases as one program (fhnn inspect and predict then "
            "give 90 % intervals over the members) [default: 1, one run]",
        ),
    ] = None,
    config_file: ConfigFileOption = None,
    set_: SetOption("model.width=32, train.lr=1e-3") = None,
    extend: Annotated[
        bool,
        typer.Option(
            "--extend",
            help="Continue a run in RUN for more Adam steps: give --steps larger than its own (the "
            "learning-rate schedule is recomputed for the new total).",
        ),
    ] = False,
    quiet: QuietOption = False,
) -> None:
    """Train a model on a data set. If RUN already holds a run it is resumed from its last
    checkpoint with its stored settings (those the data imply apply to new runs only); options
    that differ from the ones it was started with are refused (--extend allows more steps).
    Checkpoints are written at every validation and at least every minute; Ctrl-C stops the run,
    and the same command resumes it."""
    from fhnn.api.train import train as train_fit

    train_fit(
        data,
        out,
        plan=plan,
        seeds=n_seeds,
        settings=parse_params(set_ or []),
        config_file=config_file,
        model=model,
        ablation=ablation,
        steps=steps,
        seed=seed,
        max_time=max_time,
        extend=extend,
        progress=not quiet,
        started=STARTED,
    )
