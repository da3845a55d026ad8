"""``fhnn`` command line: simulate data sets and inspect them.

Every error caused by input (a bad option, parameter, file) is printed as one line
``error: <what is wrong>`` on standard error, with exit status 2 and no partial output.
"""

from __future__ import annotations

import json
import math
import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich import box
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column, Table

from fhnn.config import coerce, get_setting, read_settings_file
from fhnn.data.dataset import read_dataset, write_dataset
from fhnn.data.derivatives import AUTO_SPLINE_ROWS
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.data.summary import summarize
from fhnn.data.table import GAP_STEPS, OUTLIER_SIGMAS
from fhnn.errors import ConfigError, FhnnError
from fhnn.evaluation.predict import SAMPLES
from fhnn.experiments.grid import JOB_ADAM_STEPS, JOB_LBFGS_PAIRS, JOB_SECONDS
from fhnn.files import check_new_folder, check_output_path
from fhnn.models.registry import MODELS
from fhnn.physics.scenarios import SCENARIOS, UNITS, scenario_class
from fhnn.runtime import __version__, default_cache_dir, use_compilation_cache
from fhnn.training.plans import (
    DEFAULT_PLAN,
    PLANS,
    data_settings,
    default_settings,
    get_plan,
    is_noisy,
)

# Typer >= 0.29 vendors its own click; older releases raise click's exceptions.
_USAGE_ERRORS: tuple[type[Exception], ...] = (typer.TyperException,)
try:
    import click

    _USAGE_ERRORS += (click.exceptions.ClickException,)
except ImportError:  # pragma: no cover - depends on the Typer release
    pass


def _version(value: bool) -> None:
    if value:
        typer.echo(f"fhnn {__version__}")
        raise typer.Exit()


app = typer.Typer(
    name="fhnn",
    help="Floating-Body Hydrodynamic Neural Networks: simulate, learn and evaluate floating-body dynamics.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)

stdout = Console()
err = Console(stderr=True)


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version and exit."),
    ] = False,
) -> None:
    """Floating-Body Hydrodynamic Neural Networks: simulate, learn and evaluate floating-body dynamics.

    Compiled programs are cached in $FHNN_JAX_CACHE (default ~/.cache/fhnn/jax; "off": no cache).
    """
    use_compilation_cache(default_cache_dir())


#: Test hook of the fault tests (tests/test_faults.py): ``PHASE:N:SIGNAL`` (e.g. ``adam:40:KILL``)
#: makes a command send itself SIGNAL once its progress reaches N in PHASE — a simulated split
#: ("train", …), a training phase ("warmup", "adam", "lbfgs") or a reproduction's "jobs" /
#: "report" — so a kill lands in a chosen phase. Unset in normal use.
FAULT_ENV = "FHNN_FAULT_AT"


def _fault_point(phase: str, done: int) -> None:
    spec = os.environ.get(FAULT_ENV)
    if spec:
        where, at, name = spec.split(":")
        if where == phase and done >= int(at):
            os.kill(os.getpid(), getattr(signal, f"SIG{name}"))


class Interrupted(Exception):
    """Ctrl-C or SIGTERM stopped a command that keeps its work (train, reproduce): the message
    says what was kept; the exit status is 130."""


#: ``--config FILE`` of the commands that take settings.
ConfigFileOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="Settings file (TOML or JSON): names and [section] tables, e.g. [train] lr = 1e-3.",
    ),
]
#: ``--quiet`` of the commands with a progress bar.
QuietOption = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]


def SetOption(example: str) -> Any:
    """The ``--set NAME=VALUE`` option type, with an example of dotted names in its help."""
    return Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            metavar="NAME=VALUE",
            help=f"A setting by dotted name, e.g. {example} (repeatable; wins over --config).",
        ),
    ]


def parse_params(items: list[str], option: str = "--set") -> dict[str, str]:
    """``["NAME=VALUE", ...]`` → ``{NAME: VALUE}``; a malformed item is a :class:`ConfigError`
    naming ``option``."""
    params: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ConfigError(f"{option} expects NAME=VALUE, got {item!r}")
        params[name.strip()] = value.strip()
    return params


@app.command()
def simulate(
    scenario: Annotated[str, typer.Argument(help=f"Scenario: {', '.join(SCENARIOS)}.")],
    output: Annotated[Path, typer.Option("--output", "-o", help="HDF5 file to write.")],
    n_traj: Annotated[
        int | None, typer.Option(help="Trajectories over all splits [default: the scenario's]")
    ] = None,
    duration: Annotated[
        float | None,
        typer.Option(help="Train/val trajectory length in s [default: the scenario's]"),
    ] = None,
    test_duration: Annotated[
        float | None, typer.Option(help="Test trajectory length in s [default: the scenario's]")
    ] = None,
    dt: Annotated[float | None, typer.Option(help="Sampling interval in s [default: the scenario's]")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random draw.")] = 0,
    actuation: Annotated[
        str | None, typer.Option(help="none|random (sinusoidal forcing) [default: the scenario's]")
    ] = None,
    obs_noise: Annotated[
        float | None,
        typer.Option(help="Std of observation noise on stored states [default: the scenario's]"),
    ] = None,
    param: Annotated[
        list[str] | None,
        typer.Option(
            "--param",
            "-p",
            help="Scenario parameter NAME=VALUE (repeatable); see `fhnn scenarios`.",
        ),
    ] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar or summary.")] = False,
) -> None:
    """Simulate a ground-truth data set (train/val/test splits) and write it as HDF5."""
    cls = scenario_class(scenario)
    sc = cls.from_dict(parse_params(param or [], "--param"))
    config = SimulationConfig.for_scenario(
        sc,
        n_traj=n_traj,
        duration=duration,
        test_duration=test_duration,
        dt=dt,
        seed=seed,
        actuation=actuation,
        obs_noise=obs_noise,
    )
    check_output_path(output)
    with Progress(
        TextColumn("simulating {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=err,
        disable=quiet,
        transient=False,
    ) as bar:
        tasks: dict[str, Any] = {}

        def progress(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = bar.add_task(label, total=total)
            bar.update(tasks[label], completed=done)
            _fault_point(label, done)

        dataset = simulate_dataset(sc, config, progress=progress)
    write_dataset(dataset, output)
    if not quiet:
        _print_summary(summarize(dataset), str(output))


@app.command("import")
def import_table(
    table: Annotated[
        Path,
        typer.Argument(
            help="Table of samples (.csv or .parquet): traj_id, t, x, y[, vx, vy][, Fx, Fy] in SI "
            "units; t in seconds or as ISO-8601 date-times; a CSV separated by commas, semicolons or tabs."
        ),
    ],
    output: Annotated[Path, typer.Option("--output", "-o", help="HDF5 data set to write.")],
    mass: Annotated[float, typer.Option("--mass", help="The body's dry mass M in kg.")],
    area: Annotated[float, typer.Option("--area", help="The body's reference area A in m².")],
    rho: Annotated[float, typer.Option("--rho", help="Fluid density in kg/m³.")] = 1000.0,
    volume: Annotated[
        float | None, typer.Option("--volume", help="Displaced volume V in m³ [default: M / rho]")
    ] = None,
    split: Annotated[
        str,
        typer.Option(
            "--split", help="Percent of trajectories for train/val/test, each > 0 (each gets at least one)."
        ),
    ] = "70/20/10",
    seed: Annotated[int, typer.Option(help="Seed of the split's permutation.")] = 0,
    time_dependent: Annotated[
        bool, typer.Option("--time-dependent", help="Let models learn a flow that changes in time.")
    ] = False,
    smoother: Annotated[
        str,
        typer.Option(
            "--smoother",
            help="Velocity estimator where the table has none: spline (trains the better model), "
            "kalman (an RTS smoother, ~10x faster on large tables), or auto: the spline up to "
            f"{AUTO_SPLINE_ROWS:,} rows, kalman above.",
        ),
    ] = "auto",
    max_gap: Annotated[
        str,
        typer.Option(
            "--max-gap",
            help="Split a trajectory into pieces where two samples are more than this many seconds "
            f"apart (inf: never); auto: more than {GAP_STEPS:g}x its median step. Pieces keep the "
            "trajectory's split and are named ID#1, ID#2, ...; pieces under 3 samples are dropped "
            "and counted.",
        ),
    ] = "auto",
    outliers: Annotated[
        str,
        typer.Option(
            "--outliers",
            help="Drop a position more than this many noise levels from the cubic through its two "
            "neighbours either side (a tracker's glitch; one among a track's first or last two samples "
            "shows in its neighbours' residuals only, so it must be larger to be seen), counted in the "
            "summary; off: keep every sample.",
        ),
    ] = f"{OUTLIER_SIGMAS:g}",
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No summary.")] = False,
) -> None:
    """Import measured trajectories from a table into a data set: rows in any order, irregular times,
    unequal lengths; rows with missing values are dropped and counted; a trajectory with a long gap
    (--max-gap) becomes pieces; glitches (--outliers) are dropped and counted; velocities the table
    lacks are estimated from the positions (a smoother held to the noise level they show).
    Trajectories are split into train/val/test by a seeded permutation."""
    from fhnn.data.table import (
        ImportSettings,
        parse_max_gap,
        parse_outliers,
        parse_split,
        read_table,
        table_to_dataset,
    )

    settings = ImportSettings(
        mass=mass,
        area=area,
        rho=rho,
        volume=volume,
        split=parse_split(split),
        seed=seed,
        time_dependent=time_dependent,
        smoother=smoother,
        max_gap=parse_max_gap(max_gap),
        outlier_sigmas=parse_outliers(outliers),
    )
    check_output_path(output)
    dataset = table_to_dataset(read_table(table), settings, source=table.name)
    write_dataset(dataset, output)
    if not quiet:
        _print_summary(summarize(dataset), str(output))


@app.command()
def info(
    file: Annotated[Path, typer.Argument(help="An fhnn HDF5 data set.")],
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as JSON.")] = False,
) -> None:
    """Describe a data set: scenario, parameters, split sizes, and the ranges of r, speed and σ covered."""
    summary = summarize(read_dataset(file))
    if as_json:
        typer.echo(json.dumps(summary, indent=2, sort_keys=True))
    else:
        _print_summary(summary, str(file))


@app.command()
def scenarios() -> None:
    """List the scenarios: their parameters with units and defaults, and default data-set sizes."""
    for name, cls in SCENARIOS.items():
        d = cls.defaults
        sizes = (
            f"{d.n_traj} trajectories split {'/'.join(f'{100 * f:g}' for f in d.split)} %, train/val "
            f"{d.duration:g} s, test {d.test_duration:g} s, dt {d.dt:g} s, actuation {d.actuation}"
            + (f", observation noise {d.obs_noise:g}" if d.obs_noise else "")
        )
        stdout.print(f"\n[bold]{name}[/bold] — {cls.summary}", soft_wrap=True)
        stdout.print(f"default data set: {sizes}", soft_wrap=True, highlight=False)
        table = Table()
        table.add_column("parameter")
        table.add_column("default", justify="right")
        table.add_column("unit")
        for key, value in cls().to_dict().items():
            table.add_row(key, str(value), UNITS.get(key, ""))
        stdout.print(table)


def _settings(set_: list[str] | None, config_file: Path | None, flags: dict[str, Any]) -> dict[str, Any]:
    """Dotted settings from ``--config FILE``, then ``--set NAME=VALUE`` (which wins), then the
    dedicated flags (``flags``: setting name → (flag, value or None)); a flag that disagrees with
    the same setting given by ``--set`` or the file is refused."""
    settings: dict[str, Any] = read_settings_file(config_file) if config_file is not None else {}
    settings.update(parse_params(set_ or []))
    for name, (flag, value) in flags.items():
        if value is None:
            continue
        if name in settings and str(settings[name]) != str(value):
            try:
                same = coerce(type(value), settings[name], name) == value
            except ConfigError:
                same = False
            if not same:
                raise ConfigError(
                    f"{flag} {value} and the setting {name}={settings[name]} disagree; give one"
                )
        settings[name] = value
    return settings


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
            f"was measured with, which may differ for noisy observations; --set wins; see README) "
            f"[default: {DEFAULT_PLAN}; the training defaults on data with estimated velocities]"
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
            help="Wall-clock budget in seconds for this command's training of a run (train.max_time; "
            "compilation included, a resumed run starts a new budget): the phases before an L-BFGS "
            "polish or whole-track fit end at half of it, those at all of it, each at its next step, "
            "and the run says what was cut [default: none]",
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
    from fhnn.training.ensemble import is_ensemble, read_seeds, start_ensemble
    from fhnn.training.run import RunConfig

    if n_seeds is not None and n_seeds < 1:
        raise ConfigError(f"--seeds must be >= 1, got {n_seeds}")
    settings = _settings(
        set_,
        config_file,
        {
            "kind": ("--model", model),
            "model.ablation": ("--ablation", ablation),
            "train.steps": ("--steps", steps),
            "train.seed": ("--seed", seed),
            "train.max_time": ("--max-time", max_time),
        },
    )
    kind = str(settings.get("kind", "fhnn"))
    MODELS[kind]  # unknown kinds are refused before anything is read
    if "model.ablation" in settings and settings["model.ablation"] != "none" and kind != "fhnn":
        raise ConfigError(f"--ablation applies to fhnn only, not {kind!r}")
    given = set(settings)
    # every setting checked before any work
    RunConfig().with_settings({**(get_plan(plan).settings(kind) if plan is not None else {}), **settings})
    check_new_folder(out)
    dataset = read_dataset(data)
    if plan is not None:  # the plan's settings for these data, below any setting given
        settings = {**get_plan(plan).settings(kind, noisy=is_noisy(dataset)), **settings}
    # a new run without --plan starts from the default plan; a resumed run keeps what it stored
    start = default_settings(dataset, kind) if plan is None else {}
    # what the data's estimated fields and missing forcing call for, below any setting given; like
    # the default plan, for a new run only (a resumed run keeps what it stored, even if made before
    # these settings were implied)
    implied = {k: v for k, v in data_settings(dataset, kind).items() if k not in given}
    before = RunConfig().with_settings({**start, **settings})
    config = RunConfig().with_settings({**start, **settings, **implied})
    fresh = not (out / "run.json").exists() and not is_ensemble(out)
    said = (
        {k: v for k, v in implied.items() if get_setting(before, k) != get_setting(config, k)}
        if fresh
        else {}
    )
    notes = []  # said once the runs are open and their data checked: bad input stays one line
    masses = said.pop("model.added_mass", None)
    if masses is not None:
        notes.append(
            f"{data}: no known forcing: the added masses are not identifiable, only c/(M + m_a); "
            f"training with model.added_mass={masses} (--set wins)"
        )
    if said:
        estimated = [f for f in ("velocities", "derivatives") if f not in dataset.measured]
        with_ = ", ".join(f"{k}={v}" for k, v in said.items())
        fields = " and ".join(estimated)
        notes.append(f"{data}: {fields} were estimated, not measured: training with {with_} (--set wins)")
    default_plan = (plan or DEFAULT_PLAN) == DEFAULT_PLAN
    if fresh and "model.slow_weight" not in given and kind == "fhnn" and default_plan:
        notes += _window_weights_note(data, dataset, config)
    if n_seeds is None and is_ensemble(out):
        n_seeds = len(read_seeds(out))
        settings.setdefault("train.seed", read_seeds(out)[0])
    if n_seeds == 1 and is_ensemble(out):
        raise ConfigError(f"{out} holds an ensemble; resume it without --seeds, or train into a new folder")
    if n_seeds is None or n_seeds == 1:
        runs = [_open_run(out, settings, config, dataset, data, extend=extend)]
        _train_runs(runs, [""], dataset, quiet=quiet, notes=notes)
        return
    if "train.bootstrap" not in given:  # an ensemble's spread should hold the sampling noise
        settings["train.bootstrap"] = True
    base = int(settings.get("train.seed", 0))
    seeds = list(range(base, base + n_seeds))
    runs = []
    for seed_k, folder in zip(seeds, start_ensemble(out, seeds), strict=True):
        member = {**settings, "train.seed": seed_k}
        member_config = RunConfig().with_settings({**start, **member, **implied})
        runs.append(_open_run(folder, member, member_config, dataset, data, extend=extend))
    labels = [f"seed {s} ({k + 1}/{n_seeds}) " for k, s in enumerate(seeds)]
    _train_runs(runs, labels, dataset, quiet=quiet, notes=notes)
    if not quiet:
        stdout.print(f"ensemble of {n_seeds} runs (seeds {seeds[0]}–{seeds[-1]}) in {out}", soft_wrap=True)


def _windowless_note(run: Any, dataset: Any) -> list[str]:
    """A note where trajectories of the train or val split are too short for ``run``'s training
    windows (a user's tracks come in any length): they are left out of the loss; none otherwise."""
    window, counts = run.windowless(dataset)
    if not any(short for short, _ in counts.values()):
        return []
    names = {"train": "training", "val": "validation"}
    parts = " and ".join(
        f"{short} of {total} {names[name]}" for name, (short, total) in counts.items() if short
    )
    skip = run.train_config.first_start
    after = f" from sample {skip} on" if skip else ""
    hint = " (--set train.shoot=N for shorter windows)" if window == run.train_config.shoot else ""
    return [
        f"{parts} trajectories are shorter than the training windows ({window} samples{after}) "
        f"and are left out of the loss{hint}"
    ]


def _window_weights_note(data: Path, dataset: Any, config: Any) -> list[str]:
    """What to say of whether a new FHNN run's plan weighs its windows by their slowness, and
    why (the default plan does so on noise-free observations only): a line, or none."""
    weight = float(config.model.slow_weight)
    if weight > 0:
        text = f"noise-free observations: each window weighted by its slowness (model.slow_weight={weight:g})"
    elif is_noisy(dataset) and "slow_weight" in PLANS[DEFAULT_PLAN].noisy_model.get("fhnn", {}):
        text = (
            f"observations with noise (obs_noise {dataset.obs_noise:.3g}): windows not weighted by their "
            "slowness (model.slow_weight=0; the default plan weighs them on noise-free observations only)"
        )
    else:
        return []
    return [f"{data}: {text} (--set wins)"]


def _open_run(
    out: Path, settings: dict[str, Any], config: Any, dataset: Any, data: Path, *, extend: bool
) -> Any:
    """The run in ``out`` to train: created, or loaded to be resumed (its stored settings must
    match ``settings``; ``extend`` allows more Adam steps). A finished run is said so and
    returned as it is."""
    from fhnn.training.run import Run

    kind = str(settings.get("kind", "fhnn"))
    if (out / "run.json").exists():
        run = Run.load(out, expect_model=kind if "kind" in settings else None)
        wanted = run.config.with_settings(settings)
        if extend:
            run.extend(wanted)
        changed = run.config.differences(wanted)
        if changed:
            detail = ", ".join(
                f"{k}: {get_setting(run.config, k)!r} stored, {get_setting(wanted, k)!r} given"
                for k in changed
            )
            raise ConfigError(
                f"{out} holds a run started with other settings ({detail}); rerun without them to "
                "resume it, or train into a new folder"
            )
        if run.finished:
            if run.state.stopped is not None:
                err.print(_stopped_text(run), highlight=False, soft_wrap=True)
            stdout.print(
                f"{out} has finished training ({run.state.step} steps); nothing to do. To train further, "
                "give a larger --steps with --extend.",
                soft_wrap=True,
            )
        else:
            err.print(f"resuming {out} from step {run.state.step}", soft_wrap=True)
        return run
    if extend:
        raise ConfigError(f"--extend continues an existing run, and {out} holds none")
    return Run.create(out, dataset, config, data_path=data)


def _train_runs(
    runs: list[Any], labels: list[str], dataset: Any, *, quiet: bool, notes: Sequence[str] = ()
) -> None:
    """Train the unfinished ``runs`` — one run, or an ensemble's members (their Adam phases as
    one program: :func:`fhnn.training.ensemble.train_members`) — with a progress bar each
    (``labels[j]`` before its phase), then say how each ended; ``notes`` (what the data made of
    the settings) are said once the data are checked against the runs."""
    from fhnn.training.ensemble import train_members

    todo = [(run, label) for run, label in zip(runs, labels, strict=True) if not run.finished]
    if not todo:
        return
    for run, _ in todo:  # before the progress bar: a data set too short for the windows is one line
        run.check_windows(dataset)
    notes = [*notes, *_windowless_note(todo[0][0], dataset)]
    for note in () if quiet else notes:
        err.print(note, soft_wrap=True, highlight=False)
    names = {"lbfgs": "L-BFGS", "warmup": "warm-up", "adam": "Adam", "tracks": "tracks"}
    columns = (
        TextColumn("{task.fields[label]}{task.fields[phase]:9s}"),
        BarColumn(bar_width=20),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[losses]}", table_column=Column(no_wrap=True, overflow="ellipsis")),
    )
    with Progress(*columns, console=err, disable=quiet) as bar:
        callbacks, on_steps = [], []
        for run, label in todo:
            cfg = run.train_config
            total = cfg.steps + cfg.lbfgs_steps + cfg.track_steps
            done = run.state.step if run.state else 0
            task = bar.add_task(
                "train", total=total, completed=done, losses="", phase="compiling", label=label
            )
            callbacks.append(_progress_callback(bar, task))
            on_steps.append(_step_callback(bar, task, names))
        try:
            if len(todo) == 1:
                todo[0][0].train(dataset, callback=callbacks[0], on_step=on_steps[0])
            else:
                train_members([run for run, _ in todo], dataset, callbacks=callbacks, on_steps=on_steps)
        except KeyboardInterrupt:
            bar.stop()
            kept = "; ".join(
                f"{run.folder} keeps the checkpoint of step {run.saved_step}"
                if run.saved_step is not None
                else f"nothing was saved in {run.folder} yet"
                for run, _ in todo
            )
            raise Interrupted(f"interrupted: {kept}; run the same command again to resume") from None
    for run, _ in todo:
        if run.state.stopped is not None:  # said even with -q: the run ended before its plan did
            err.print(_stopped_text(run), highlight=False, soft_wrap=True)
        if not quiet:
            decided = [r for r in run.state.history if "warmup" in r]
            if decided:
                err.print(_warmup_text(decided[-1], run.train_config), highlight=False, soft_wrap=True)
            best = run.state.best_val
            stdout.print(
                f"trained {run.kind} for {run.state.step} steps; best validation loss {best:.3e}; saved to "
                f"{run.folder}",
                soft_wrap=True,
            )


def _progress_callback(bar: Progress, task: Any) -> Any:
    """A record callback that moves ``task`` to the record's step and shows its losses."""

    def progress(state: Any, record: dict[str, float]) -> None:  # every term is in run.json
        fit = (
            f"tracks {record['track_mean_square']:.2e} m²"
            if "track_mean_square" in record
            else f"train {record['train_loss']:.1e}"
        )
        losses = f"{fit} val {record['val_total']:.1e}"
        if math.isfinite(record.get("val_forecast", math.nan)):  # the whole-track fit's guard
            losses = f"{fit} val forecast {record['val_forecast'] * 1e3:.2f} mm"
        bar.update(task, completed=state.step, losses=losses)

    return progress


def _step_callback(bar: Progress, task: Any, names: dict[str, str]) -> Any:
    """A step callback that moves ``task`` (at most every 0.1 s, and at each new phase)."""
    told = {"phase": "", "at": 0.0}

    def stepped(phase: str, step: int) -> None:
        _fault_point(phase, step)
        now = time.monotonic()
        if phase != told["phase"] or now - told["at"] >= 0.1:
            told.update(phase=phase, at=now)
            bar.update(task, completed=step, phase=names.get(phase, phase))

    return stepped


def _warmup_text(record: dict[str, Any], train: Any) -> str:
    """What the warm-up's validation loss decided (``train.warmup_accept``)."""
    val, accept = record["val_total"], train.warmup_accept
    if record["warmup"] == "kept":
        return f"warm-up kept (validation loss {val:.2e} <= {accept:g}): Adam skipped, polished from it"
    return (
        f"warm-up discarded at iteration {record['iteration']} of {train.warmup_steps} (validation loss "
        f"{val:.2e} > {accept:g}: the linear far field does not explain this flow); Adam started from "
        "the initial model"
    )


def _stopped_text(run: Any) -> str:
    """The line saying that a guard stopped ``run`` early, and which model it kept."""
    best = min(
        (r for r in run.state.history if r.get("val_total") == run.state.best_val),
        key=lambda r: r["step"],
        default={"step": "?"},
    )
    return (
        f"{run.state.stopped}; the result is the best model (validation loss {run.state.best_val:.3e}, "
        f"step {best['step']})"
    )


#: Horizons [s] ``fhnn evaluate`` reports when none are given (those the trajectories allow).
DEFAULT_HORIZONS = (1, 2, 5, 16, 60)


def finite_or_null(value: Any) -> Any:
    """``value`` with every non-finite float (in nested dicts and lists) replaced by ``None``: strict
    JSON has no infinity or NaN."""
    if isinstance(value, dict):
        return {k: finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_null(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@app.command()
def evaluate(
    run_dir: Annotated[Path, typer.Argument(help="Run folder (or ensemble folder) written by `fhnn train`.")],
    data: Annotated[
        Path | None, typer.Argument(help="Data set [default: the one the run was trained on]")
    ] = None,
    horizons: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated horizons in whole seconds [default: those of 1,2,5,16,60 that the "
            "trajectories last]."
        ),
    ] = None,
    split: Annotated[str, typer.Option(help="train|val|test")] = "test",
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print {horizon: {metric: value}} as strict JSON; an error that is infinite (a "
            'rollout diverged, see diverged_count) is null. On an ensemble: {"mean": …, "std": …, '
            '"members": {seed: …}}.',
        ),
    ] = False,
) -> None:
    """Roll the best model out from each trajectory's first state and report errors at horizons.
    On an ensemble (fhnn train --seeds N): every member, and each error's mean over the members."""
    from fhnn.data.dataset import SPLITS
    from fhnn.evaluation.evaluate import evaluate as run_evaluation
    from fhnn.evaluation.evaluate import evaluate_ensemble

    if split not in SPLITS:
        raise ConfigError(f"--split must be one of {', '.join(SPLITS)}, got {split!r}")
    hs: list[float] = []
    if horizons is not None:
        try:
            hs = [float(h) for h in horizons.split(",") if h.strip()]
        except ValueError:
            raise ConfigError(f"--horizons expects numbers separated by commas, got {horizons!r}") from None
    folders, runs, dataset = _load_runs(run_dir, data)
    if horizons is None:
        length = dataset[split].duration
        hs = [float(h) for h in DEFAULT_HORIZONS if h <= length + 1e-9]
        if not hs:
            raise ConfigError(
                f"the {split} trajectories last {length:g} s, shorter than the shortest horizon (1 s)"
            )
        if len(hs) < len(DEFAULT_HORIZONS):
            err.print(
                f"horizons {', '.join(f'{h:g}' for h in hs)} s: the {split} trajectories last {length:g} s "
                "(--horizons chooses others)",
                highlight=False,
                soft_wrap=True,
            )
    if len(runs) > 1:
        ens = evaluate_ensemble([r.state.best_model for r in runs], dataset, hs, split=split)
        rows, n_traj = ens["mean"], len(ens["members"][0]["diverged"])
        title = (
            f"ensemble {run_dir} on {split} ({n_traj} trajectories): mean over its "
            f"{len(runs)} members (diverged: their total; --json: each member and the std)"
        )
        json_out = {
            "mean": ens["mean"],
            "std": ens["std"],
            "members": {
                f.name: {**m["horizons"], "diverged_count": int(sum(m["diverged"]))}
                for f, m in zip(folders, ens["members"], strict=True)
            },
            "diverged_count": ens["diverged"],
        }
    else:
        result = run_evaluation(runs[0].state.best_model, dataset, hs, split=split)
        rows = result["horizons"]
        title = f"{run_dir} on {split} ({len(result['diverged'])} trajectories)"
        json_out = {**rows, "diverged_count": int(sum(result["diverged"]))}
    if as_json:
        typer.echo(json.dumps(finite_or_null(json_out), indent=2, allow_nan=False))
        return
    table = Table(
        title=title,
        title_justify="left",
        box=box.SIMPLE_HEAD,
        padding=(0, 0, 0, 1),
    )
    columns = {  # header (two lines, so that the table fits 80 columns), format
        "rmse_pos": ("RMSE\npos [m]", "{:.3g}"),
        "rmse_vel": ("RMSE\nvel [m/s]", "{:.3g}"),
        "ade": ("ADE\n[m]", "{:.3g}"),
        "fde": ("FDE\n[m]", "{:.3g}"),
        "within_eps": ("within\n1 cm", "{:.0%}"),
        "skill": ("LW\nskill", "{:.2f}"),
        "diverged": ("diverged", "{:d}"),
        "outside_training": ("left\ntraining", "{:.0%}"),
    }
    table.add_column("H \\[s]", justify="right")
    for header, _ in columns.values():
        table.add_column(header, justify="right")
    for h, m in rows.items():
        table.add_row(h, *(fmt.format(m[c]) for c, (_, fmt) in columns.items()))
    stdout.print(table)


@app.command()
def predict(
    run_dir: Annotated[
        Path,
        typer.Argument(
            help="Run folder (or ensemble folder) written by `fhnn train` (a vector-field model)."
        ),
    ],
    duration: Annotated[float, typer.Option("--duration", help="Forecast length in seconds.")],
    initial: Annotated[
        str | None,
        typer.Option("--initial", help="Start state x,y,vx,vy [m, m, m/s, m/s] at --t0."),
    ] = None,
    t0: Annotated[
        float,
        typer.Option(
            "--t0",
            help="Time of --initial in seconds on the clock of the run's data (an imported table's "
            "own seconds, or seconds after its first date-time).",
        ),
    ] = 0.0,
    history: Annotated[
        Path | None,
        typer.Option(
            "--history",
            help="Observed tracks (.csv/.parquet as for fhnn import: traj_id, t, x, y[, vx, vy][, Fx, "
            "Fy]): each is forecast from its last sample, its state there fitted to its last "
            "--fit-window seconds.",
        ),
    ] = None,
    forcing: Annotated[
        Path | None,
        typer.Option(
            "--forcing",
            help="Known forces over the forecast (.csv/.parquet: t, Fx, Fy[, traj_id]) [default: none].",
        ),
    ] = None,
    dt: Annotated[
        float | None,
        typer.Option("--dt", help="Output step in seconds [default: the history's median step, or 0.05]."),
    ] = None,
    fit_window: Annotated[
        float | None,
        typer.Option(
            "--fit-window", help="Seconds of each history the start state is fitted to [default: 1]."
        ),
    ] = None,
    samples: Annotated[
        int,
        typer.Option(
            "--samples",
            help="Start states drawn from each fitted track's uncertainty and forecast for the band "
            "(with --history; 0: none).",
        ),
    ] = SAMPLES,
    outliers: Annotated[
        str,
        typer.Option(
            "--outliers",
            help="Drop a --history position more than this many noise levels (as the history shows "
            "them) from the cubic through its neighbours before fitting, as fhnn import does; off: keep all.",
        ),
    ] = f"{OUTLIER_SIGMAS:g}",
    output: Annotated[
        Path | None,
        typer.Option(
            "--output", "-o", help="Write the forecast here (.csv or .parquet) [default: CSV on stdout]."
        ),
    ] = None,
) -> None:
    """Forecast with a trained model from a given state or from the end of observed tracks: columns
    traj_id, t, x, y, vx, vy; with a band — from an ensemble (fhnn train --seeds N), from
    --history, or both — then x_lo, x_hi, y_lo, … (5th and 95th percentiles over the members'
    forecasts and those from start states drawn from each fit's uncertainty; x, y, … are the
    members' median). A history's start state is the one the model explains best (a least squares
    fit of its trajectory to the last observed positions), not a smoother's end point. Times are on
    the clock of the table the run's data were imported from — its seconds, or date-times where it
    gave date-times — for --t0, the history and the forcing alike; the forecast's t is on that
    clock too, as date-times where the history gave date-times."""
    from fhnn.data.table import (
        SECONDS_ONLY,
        check_table_name,
        drop_table_outliers,
        parse_outliers,
        read_forcing,
        read_table,
        seconds_to_date_times,
        shift_times,
        write_table,
    )
    from fhnn.evaluation.predict import FIT_WINDOW, Forecast, predict_tracks
    from fhnn.models.base import AbstractVectorField
    from fhnn.training.ensemble import INTERVAL, is_ensemble, member_folders
    from fhnn.training.run import Run

    if (initial is None) == (history is None):
        raise ConfigError("give --initial x,y,vx,vy or --history TABLE (one of them)")
    state = None
    if initial is not None:
        try:
            state = [float(v) for v in initial.split(",")]
        except ValueError:
            raise ConfigError(f"--initial expects x,y,vx,vy as four numbers, got {initial!r}") from None
        if len(state) != 4:
            raise ConfigError(f"--initial expects x,y,vx,vy as four numbers, got {initial!r}")
    sigmas = parse_outliers(outliers)
    if output is not None:
        check_output_path(output)
        check_table_name(output)
    folders = member_folders(run_dir) if is_ensemble(run_dir) else [run_dir]
    models = []
    for folder in folders:
        run = Run.load(folder)
        if not isinstance(run.state.best_model, AbstractVectorField):
            raise ConfigError(
                f"predict needs a vector-field model; a {run.kind!r} model steps on its own grid"
            )
        models.append(run.state.best_model)
    # every time given is on the clock of the table the run's data came from; the model's t = 0
    # is that clock's `offset` (the imported table's first sample)
    clock = run.clock()
    origin, offset = clock["origin"], clock["offset"]
    if "unknown" in clock:
        err.print(
            f"note: the clock of the table behind {run_dir} is unknown — {clock['unknown']}: times "
            "are read as the model's own (its t = 0 the table's first sample)",
            highlight=False,
        )
    read_origin = SECONDS_ONLY if origin is None else origin
    tracks = read_table(history, read_origin) if history is not None else None
    glitches = 0
    if tracks is not None:
        tracks, glitches = drop_table_outliers(tracks, sigmas)
    forces = read_forcing(forcing, read_origin) if forcing is not None else None
    dates = tracks is not None and tracks.time_origin is not None
    if offset:
        if tracks is not None:
            tracks = shift_times(tracks, -offset)
        if forces is not None:
            forces = {k: (t - offset, f) for k, (t, f) in forces.items()}
    if dt is None:
        dt = (
            float(np.median(np.concatenate([np.diff(tr.t) for tr in tracks.trajectories])))
            if tracks
            else 0.05
        )
    forecasts = [
        predict_tracks(
            model,
            duration=duration,
            dt=dt,
            initial=None if state is None else np.asarray(state),
            t0=t0 - offset,
            history=tracks,
            forcing_table=forces,
            fit_window=FIT_WINDOW if fit_window is None else fit_window,
            samples=samples,
        )
        for model in models
    ]
    banded = len(forecasts) > 1 or forecasts[0].samples is not None
    result = Forecast.of_ensemble(forecasts, INTERVAL) if banded else forecasts[0]
    if forces is None:
        err.print("note: no --forcing: the forecast assumes no external force", highlight=False)
    if glitches:
        err.print(
            f"note: {glitches} position(s) of the history lay more than {sigmas:g} noise levels from the "
            "cubic through their neighbours and were left out of the fit (--outliers off keeps them)",
            highlight=False,
        )
    if tracks is not None:
        err.print(
            f"fitted {len(result.ids)} track(s): RMS position residual median "
            f"{float(np.median(result.fit_rms)):.3g} m (about the noise when the model explains them)",
            highlight=False,
        )
    failed = [i for i, ok in zip(result.ids, result.ok, strict=True) if not ok]
    if failed:
        err.print(f"warning: the forecast of {', '.join(failed)} diverged", highlight=False)
    columns = result.columns()
    columns["t"] = columns["t"] + offset
    if dates:  # the history gave date-times: so does the forecast
        columns["t"] = seconds_to_date_times(columns["t"], origin)
    if output is not None:
        write_table(columns, output)
        err.print(f"wrote {output}", highlight=False)
        return
    names = list(columns)
    typer.echo(",".join(names))
    for row in zip(*(columns[c] for c in names), strict=True):
        typer.echo(",".join(str(v) if isinstance(v, str) else repr(float(v)) for v in row))


def _exports(model: Any, dataset: Any, run_dir: Path) -> list[Path]:
    """``coefficients.csv`` and ``flow.nc`` in the run folder (:mod:`fhnn.experiments.exports`)."""
    from fhnn.experiments.exports import write_coefficients_csv, write_flow_netcdf

    return [
        write_coefficients_csv(model.eom, dataset, run_dir / "coefficients.csv"),
        write_flow_netcdf(model.flow, dataset, run_dir / "flow.nc"),
    ]


def _drag_note(sigma_min: float) -> str:
    """What data with known forcing say about c_q and c_l apart (printed under the coefficients;
    without known forcing the note on the ratios c/(M + m_a) stands instead)."""
    return (
        "note: c_q and c_l share the drag; the data fix their sum, the total drag coefficient "
        "drag = ½ρA c_q σ + c_l [N·s/m], more tightly than the split, which rests on how the drag "
        f"changes with σ down to the slowest relative speed in the data ({_fmt(sigma_min)} m/s)"
    )


def _held_masses_note(model: Any) -> str:
    """What to add to the no-forcing notes where training held the added masses to two constants
    (``model.added_mass="constant"``, :func:`fhnn.training.plans.data_settings`): their values
    are where training left a free gauge, not estimates. Empty otherwise."""
    if getattr(model.coefficients, "mass_raw", None) is None:
        return ""
    return (
        " Training held the added masses to two constants (model.added_mass=constant), since the "
        "data cannot fix them: their values are where training left that free gauge."
    )


def _inspect_learned(run_dir: Path, model: Any, dataset: Any, as_json: bool) -> None:
    """``fhnn inspect`` on imported data: the learned coefficients and flow, no truth to compare."""
    from fhnn.evaluation.recovery import learned_coefficients
    from fhnn.experiments.figures import coefficient_figure, flow_figure

    coef = learned_coefficients(model.eom, dataset)
    written = _exports(model, dataset, run_dir)
    written += flow_figure(model.flow, None, dataset, run_dir / "flow")
    written += coefficient_figure(
        model.coefficients, None, dataset, run_dir / "coefficients", flow_of=model.eom
    )
    if as_json:
        typer.echo(json.dumps({"coefficients": coef, "written": [str(f) for f in written]}, indent=2))
        return
    table = Table(
        title="learned coefficients over the (r, σ) the training data cover (σ in the learned flow)",
        title_justify="left",
    )
    for col in ("coefficient", "median", "range"):
        table.add_column(col, justify="right")
    for name in ("m_ax", "m_ay", "c_q", "c_l", "drag"):
        c = coef[name]
        table.add_row(name, _fmt(c["median"]), f"{_fmt(c['learned_min'])} – {_fmt(c['learned_max'])}")
    stdout.print(table)
    cov = coef["_coverage"]
    stdout.print(
        f"covered: r {_fmt(cov['r_min'])} – {_fmt(cov['r_max'])} m, σ {_fmt(cov['sigma_min'])} – "
        f"{_fmt(cov['sigma_max'])} m/s; no ground truth: these are estimates, not recovery errors",
        soft_wrap=True,
    )
    forced = dataset.known_forcing
    if forced:
        stdout.print(_drag_note(cov["sigma_min"]), soft_wrap=True)
    else:
        stdout.print(
            "note: no known forcing in the data (no Fx, Fy, or all zero) — the added masses and drag "
            "coefficients above are NOT determined by the data (scaling inertia and drag together "
            "changes nothing a neutrally buoyant body does); what is identifiable are the ratios, "
            "drag/(M + m_a) most tightly (the relative velocity's relaxation rate [1/s] at each σ; its "
            "split between c_q and c_l rests on the slowest relative speeds in the data)."
            + _held_masses_note(model)
            + " The ratios:",
            soft_wrap=True,
        )
        ratios = Table(title="identifiable ratios over the covered (r, σ)", title_justify="left")
        for col in ("ratio", "median", "range"):
            ratios.add_column(col, justify="right")
        for name, r in coef["_ratios"].items():
            ratios.add_row(name, _fmt(r["median"]), f"{_fmt(r['learned_min'])} – {_fmt(r['learned_max'])}")
        stdout.print(ratios)
    stdout.print("written: " + ", ".join(str(f) for f in written))


def _inspect_ensemble(folder: Path, data: Path | None, as_json: bool) -> None:
    """``fhnn inspect`` on an ensemble: each coefficient and identifiable ratio with the members'
    median and 90 % interval (against the truth where the data were simulated), and the
    ``coefficients.csv`` / ``flow.nc`` of the ensemble (with ``_lo`` / ``_hi``) in the folder."""
    from fhnn.evaluation.recovery import visited_r_sigma
    from fhnn.experiments.exports import ensemble_intervals, write_coefficients_csv, write_flow_netcdf
    from fhnn.training.ensemble import LEVEL

    _, runs, dataset = _load_runs(folder, data, fhnn_only=True)
    models = [r.state.best_model for r in runs]
    truth = None if dataset.imported else dataset.equations()
    rows = ensemble_intervals([m.eom for m in models], dataset, truth)
    written = [
        write_coefficients_csv([m.eom for m in models], dataset, folder / "coefficients.csv"),
        write_flow_netcdf([m.flow for m in models], dataset, folder / "flow.nc"),
    ]
    forced = dataset.known_forcing
    # identifiability from the spread: without known forces inertia and drag scale together, so
    # the members agree on the ratios c/(M + m_a) far better than on the masses themselves
    mass_width = max(rows[n]["rel_width"] for n in ("m_ax", "m_ay"))
    ratio_width = max(rows[n]["rel_width"] for n in rows if "/" in n)
    drag_width = max(rows[n]["rel_width"] for n in rows if n.startswith("drag/"))
    if as_json:
        out = {
            "members": len(models),
            "coefficients": rows,
            "forced": forced,
            "written": [str(f) for f in written],
        }
        typer.echo(json.dumps(out, indent=2))
        return
    table = Table(
        title=f"ensemble of {len(models)} runs: median and 90 % interval from the members, "
        "typical over the covered (r, σ)",
        title_justify="left",
    )
    columns = ["quantity", "median", "90 % interval", "rel. width"]
    if truth is not None:
        columns += ["true", "truth inside", "max rel. error"]
    for col in columns:
        table.add_column(col, justify="right")
    for name, r in rows.items():
        cells = [name, _fmt(r["median"]), f"{_fmt(r['lo'])} – {_fmt(r['hi'])}", f"{r['rel_width']:.1%}"]
        if truth is not None:
            cells += [_fmt(r["true"]), f"{r['coverage']:.0%} of points", f"{r['max_rel']:.2%}"]
        table.add_row(*cells)
    stdout.print(table)
    if forced:
        stdout.print(_drag_note(visited_r_sigma(models[0].eom, dataset)[:, 1].min()), soft_wrap=True)
    else:
        stdout.print(
            "note: no known forcing in the data — the added masses and drag coefficients are NOT "
            "determined by the data; only the ratios c/(M + m_a) are (the members' masses spread "
            f"{mass_width:.1%}, their ratios {ratio_width:.1%}; the total drag's, drag/(M + m_a), "
            f"{drag_width:.1%}: the split between c_q and c_l rests on the slowest relative speeds)."
            + _held_masses_note(models[0]),
            soft_wrap=True,
        )
    bootstrap = all(r.train_config.bootstrap for r in runs)
    stdout.print(
        f"the interval: the members' mean ± t({0.5 + LEVEL / 2:g}; {len(models) - 1}) · s · "
        f"√(1 + 1/{len(models)}) "
        + (
            "— members trained on bootstrap weightings of the data, so it holds the data's sampling "
            "noise and the initialisation's, not a bias that every member shares (such as the "
            "split of the drag between c_q and c_l)"
            if bootstrap
            else "— members trained on the same data: it holds their initialisation and batch order, "
            "not the data's sampling noise"
        ),
        soft_wrap=True,
    )
    stdout.print("written: " + ", ".join(str(f) for f in written))


@app.command()
def inspect(
    run_dir: Annotated[Path, typer.Argument(help="Run folder (or ensemble folder) written by `fhnn train`.")],
    data: Annotated[
        Path | None, typer.Argument(help="Data set [default: the one the run was trained on]")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the recovery numbers as JSON.")] = False,
) -> None:
    """Learned coefficients against the truth, flow recovery, and figures (PNG) written into RUN,
    with the learned coefficients over the covered (r, σ) as coefficients.csv and the learned flow
    on a grid as flow.nc (NetCDF-4). On imported data (no truth): the learned coefficients over
    the region the data cover, and the learned flow. On an ensemble (fhnn train --seeds N): every
    coefficient and identifiable ratio with the members' median and 90 % interval (and whether it
    covers the truth), coefficients.csv with NAME_lo/NAME_hi columns and flow.nc with u_lo, u_hi, …"""
    from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
    from fhnn.experiments.figures import coefficient_figure, flow_figure
    from fhnn.training.ensemble import is_ensemble

    if is_ensemble(run_dir):
        _inspect_ensemble(run_dir, data, as_json)
        return
    run, dataset = _load_run(run_dir, data, fhnn_only=True)
    model = run.state.best_model
    if dataset.imported:
        _inspect_learned(run_dir, model, dataset, as_json)
        return
    coef = coefficient_recovery(model.coefficients, dataset)
    flow = flow_recovery(model.flow, dataset)
    truth = dataset.equations()
    written = _exports(model, dataset, run_dir)
    written += flow_figure(model.flow, truth.flow, dataset, run_dir / "flow")
    written += coefficient_figure(model.coefficients, truth.coefficients, dataset, run_dir / "coefficients")
    init = dict(zip(("m_ax", "m_ay", "c_q", "c_l"), run.model_config.init_coefficients, strict=True))
    coef["_near_initial"] = [
        n
        for n, v in init.items()
        if max(abs(coef[n]["learned_min"] - v), abs(coef[n]["learned_max"] - v)) < 0.05 * v
    ]
    if as_json:
        typer.echo(
            json.dumps({"coefficients": coef, "flow": flow, "written": [str(f) for f in written]}, indent=2)
        )
        return
    table = Table(title="coefficients over the (r, σ) the training data covers", title_justify="left")
    for col in ("coefficient", "learned range", "true range", "mean rel. error", "max rel. error"):
        table.add_column(col, justify="right")
    for name in ("m_ax", "m_ay", "c_q", "c_l"):
        c = coef[name]
        table.add_row(
            name,
            f"{_fmt(c['learned_min'])} – {_fmt(c['learned_max'])}",
            f"{_fmt(c['true_min'])} – {_fmt(c['true_max'])}",
            f"{c['mean_rel']:.2%}",
            f"{c['max_rel']:.2%}",
        )
    d = coef["_drag"]
    table.add_row(
        "drag",
        f"{_fmt(d['learned_min'])} – {_fmt(d['learned_max'])}",
        f"{_fmt(d['true_min'])} – {_fmt(d['true_max'])}",
        f"{d['mean_rel']:.2%}",
        f"{d['max_rel']:.2%}",
    )
    stdout.print(table)
    if dataset.actuation != "none":  # unforced, even the total drag is fixed only relative to inertia
        stdout.print(_drag_note(coef["_coverage"]["sigma_min"]), soft_wrap=True)
    bands = Table(
        title="c_q by σ band (quantiles of the visited σ); small quadratic share: c_q weakly constrained",
        title_justify="left",
    )
    for col in ("σ [m/s]", "points", "quadratic share of drag", "c_q max rel. error", "drag max rel. error"):
        bands.add_column(col, justify="right")
    for b in coef["_by_sigma"]:
        bands.add_row(
            f"{_fmt(b['sigma_lo'])} – {_fmt(b['sigma_hi'])}",
            str(b["points"]),
            f"{b['quadratic_share']:.1%}",
            f"{b['c_q']:.2%}",
            f"{b['drag']:.2%}",
        )
    stdout.print(bands)
    still = coef["_near_initial"]
    if still:
        stdout.print(
            f"note: {', '.join(still)} still lie within 5 % of their initial values "
            f"({', '.join(f'{n} = {init[n]:g}' for n in still)}): training has barely moved them, so they "
            "say little yet; train longer (fhnn train ... --steps N --extend).",
            soft_wrap=True,
        )
    if dataset.actuation == "none":
        stdout.print(
            "note: trained without actuation — only the ratios c / (M + m_a) are identifiable, the "
            "total drag's drag / (M + m_a) most tightly; the absolute masses and drag coefficients "
            "above are not measured quantities."
            + _held_masses_note(model)
            + " The ratios: "
            + ", ".join(
                f"{name} {r['mean_rel']:.2%} mean / {r['max_rel']:.2%} max rel. error"
                for name, r in coef["_ratios"].items()
            ),
            soft_wrap=True,
        )
    when = (
        f", {len(flow['times'])} times over {flow['times'][0]:g}–{flow['times'][-1]:g} s"
        if len(flow["times"]) > 1
        else ""
    )
    stdout.print(f"flow: relative L2 error {flow['rel_l2']:.3%} over {flow['points']} grid points{when}")
    stdout.print("written: " + ", ".join(str(f) for f in written))


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
    from fhnn.experiments.executors import check_workers
    from fhnn.experiments.grid import ReproduceConfig, build_grid
    from fhnn.experiments.reproduce import check_output_folder
    from fhnn.experiments.reproduce import reproduce as run_reproduction

    settings = _settings(set_, config_file, {"seeds": ("--seeds", seeds), "train.steps": ("--steps", steps)})
    config = ReproduceConfig.quick(settings) if quick else ReproduceConfig().with_settings(settings)
    if workers is not None:
        check_workers(workers)
    check_output_folder(out)
    n_data, n_jobs = (len(x) for x in build_grid(config))
    err.print(f"reproduce: {n_data} data sets, {n_jobs} training jobs ({config.seeds} seed(s)) -> {out}")
    with Progress(
        TextColumn("{task.fields[phase]:6s}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[last]}"),
        console=err,
        disable=quiet,
    ) as bar:
        task = bar.add_task("reproduce", total=1, phase="", last="")

        def progress(phase: str, done: int, total: int, last: str) -> None:
            bar.update(task, completed=done, total=total, phase=phase, last=last)
            _fault_point(phase, done)

        try:
            summary = run_reproduction(config, out, workers=workers, ray_address=ray, progress=progress)
        except KeyboardInterrupt:
            bar.stop()
            kept = "interrupted: finished jobs are kept; run the same command again to resume"
            raise Interrupted(kept) from None
    ran = (
        f"{summary.data_run} of {summary.data_total} data sets and "
        f"{summary.jobs_run} of {summary.jobs_total} training jobs run"
    )
    built = "report rebuilt" if summary.report_built else "nothing changed, report kept"
    stdout.print(f"{ran}, {built} in {summary.seconds:.0f} s: {out / 'index.html'}")


def _load_runs(
    run_dir: Path, data: Path | None, *, fhnn_only: bool = False
) -> tuple[list[Path], list[Any], Any]:
    """The folders and runs of the run in ``run_dir``, or of every member of the ensemble there,
    and the data set to score them on (read once, as :func:`_load_run` finds it for the first)."""
    from fhnn.training.ensemble import is_ensemble, member_folders
    from fhnn.training.run import Run

    folders = member_folders(run_dir) if is_ensemble(run_dir) else [run_dir]
    first, dataset = _load_run(folders[0], data, fhnn_only=fhnn_only)
    return folders, [first] + [Run.load(f) for f in folders[1:]], dataset


def _load_run(run_dir: Path, data: Path | None, *, fhnn_only: bool = False) -> tuple[Any, Any]:
    """A trained run and the data set to score it on (default: the one it was trained on, found
    relative to the run folder and checked against its SHA-256)."""
    from fhnn.training.ensemble import is_ensemble, member_folders
    from fhnn.training.run import Run

    if is_ensemble(run_dir):
        members = ", ".join(str(f) for f in member_folders(run_dir))
        raise ConfigError(f"{run_dir} is an ensemble; give one of its runs ({members})")
    run = Run.load(run_dir)
    if fhnn_only and run.kind != "fhnn":
        raise ConfigError(f"inspect needs an fhnn run; a {run.kind!r} model has no flow or coefficients")
    if run.state is not None and run.state.stopped is not None:
        err.print(f"note: {_stopped_text(run)}", highlight=False, soft_wrap=True)
    return run, read_dataset(data) if data is not None else run.dataset()


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def _law_text(law: dict[str, Any]) -> str:
    params = ", ".join(f"{k}={_fmt(v)}" for k, v in law.items() if k != "law")
    return f"{law['law']}({params})"


def _print_summary(summary: dict[str, Any], path: str) -> None:
    stdout.print(
        f"[bold]{path}[/bold]: scenario [bold]{summary['scenario']}[/bold], seed {summary['seed']}, "
        f"dt {summary['dt']} s, actuation {summary['actuation']}, obs_noise {summary['obs_noise']}, "
        f"written by fhnn {summary['version']}"
    )
    body = summary["body_params"]
    record = summary["imported"]
    if record:  # a user's measurements: what was measured, estimated, dropped
        stdout.print(
            f"imported from {record['source'] or '?'}: {record['rows']} rows, {record['dropped_rows']} "
            f"dropped (missing values), {record['trajectories']} trajectories; sample step median "
            f"{_fmt(record['step_median'])} s (range {_fmt(record['step_range'][0])} – "
            f"{_fmt(record['step_range'][1])} s)"
            + (f"; times read as seconds after {record['time_origin']}" if record.get("time_origin") else ""),
            soft_wrap=True,
            highlight=False,
        )
        if record.get("gaps_split"):
            limit = (
                f"{_fmt(record['gap_steps'])}x the trajectory's median step"
                if record["max_gap"] is None
                else f"{_fmt(record['max_gap'])} s"
            )
            stdout.print(
                f"gaps: {record['gaps_split']} gap(s) longer than {limit} split {record['tracks_split']} of "
                f"the table's {record['tracks']} trajectories into pieces named ID#1, ID#2, ...; "
                f"{record['short_pieces_dropped']} piece(s) under 3 samples dropped "
                f"({record['short_piece_rows']} rows)",
                soft_wrap=True,
                highlight=False,
            )
        if record.get("outliers_dropped"):
            stdout.print(
                f"outliers: {record['outliers_dropped']} position(s) in {record['outlier_trajectories']} "
                f"trajectories lay more than {_fmt(record['outlier_sigmas'])} noise levels from the cubic "
                "through their neighbours (a tracker's glitches?) and were dropped "
                "(--outliers off keeps them)",
                soft_wrap=True,
                highlight=False,
            )
        vel_noise, vel_error = record["velocity_noise"], record.get("velocity_error")
        stdout.print(
            f"measured: {', '.join(summary['measured'])}; "
            f"position noise seen: {_fmt(record['position_noise'])} m"
            + (f", velocity noise seen: {_fmt(vel_noise)} m/s" if vel_noise is not None else "")
            + (f", estimated velocities' RMS error: {_fmt(vel_error)} m/s" if vel_error is not None else "")
            + f"; velocities: {record['velocity']}",
            soft_wrap=True,
            highlight=False,
        )
        stdout.print(
            f"body: M={body['M']} kg, rho={body['rho']} kg/m³, A={body['A']} m², V={_fmt(body['V'])} m³"
        )
    else:
        params = ", ".join(
            f"{k}={v}" for k, v in summary["scenario_params"].items() if k != "modes" and v is not None
        )
        stdout.print(f"parameters: {params}")
        if summary["scenario_params"].get("modes"):
            stdout.print(f"flow perturbation: {len(summary['scenario_params']['modes'])} frozen modes")
        laws = "; ".join(f"{k} {_law_text(body[k])}" for k in ("m_ax", "m_ay", "c_q", "c_l"))
        stdout.print(f"body: M={body['M']} kg, rho={body['rho']} kg/m³, A={body['A']} m²; {laws}")
    if any(summary["redraws"].values()):
        stdout.print(f"redrawn trajectories (too close to the obstacle): {summary['redraws']}")
    splits = summary["splits"]
    sizes = Table(title="splits", title_justify="left")
    for col in ("split", "trajectories", "samples", "duration \\[s]"):
        sizes.add_column(col, justify="right")
    for name, s in splits.items():
        sizes.add_row(name, str(s["n_traj"]), str(s["n_times"]), _fmt(s["duration"]))
    stdout.print(sizes)
    states = "observed states" if summary["imported"] else "clean states"  # no truth in measured data
    cover = Table(title=f"coverage of the {states} (min – max)", title_justify="left")
    cover.add_column("quantity")
    for name in splits:
        cover.add_column(name, justify="right", no_wrap=True)
    labels = {"r": "r \\[m]", "speed": "|v| \\[m/s]", "sigma": "σ \\[m/s]", "force": "|F_ext| \\[N]"}
    for key, label in labels.items():
        if key not in next(iter(splits.values()))["coverage"]:
            continue  # σ needs the true flow
        cells = [f"{_fmt(s['coverage'][key][0])} – {_fmt(s['coverage'][key][1])}" for s in splits.values()]
        cover.add_row(label, *cells)
    stdout.print(cover)


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
