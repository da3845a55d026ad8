"""``fhnn.train``: train a run or an ensemble on a data set, as ``fhnn train`` does."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column

from fhnn.api.fit import Fit, stopped_text
from fhnn.api.report import Reporter, fault_point, reporter
from fhnn.config import flatten, get_setting
from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.errors import ConfigError, Interrupted
from fhnn.files import check_new_folder
from fhnn.training.budget import Budget
from fhnn.training.ensemble import is_ensemble, read_seeds, start_ensemble, train_members
from fhnn.training.run import Run, RunConfig
from fhnn.training.settings import Resolution, check_settings, given_settings, resolve, source_name

#: Where a run trained on a data set in memory keeps it (in the run's or the ensemble's folder).
DATA_FILE = "data.h5"

#: How the progress bar names the training phases.
PHASE_NAMES = {"lbfgs": "L-BFGS", "warmup": "warm-up", "adam": "Adam", "tracks": "tracks"}


def train(
    data: Dataset | str | os.PathLike[str],
    out: str | os.PathLike[str],
    config: RunConfig | None = None,
    *,
    plan: str | None = None,
    seeds: int | None = None,
    settings: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
    model: str | None = None,
    ablation: str | None = None,
    steps: int | None = None,
    seed: int | None = None,
    max_time: float | None = None,
    extend: bool = False,
    progress: Reporter | bool = True,
    started: float | None = None,
) -> Fit:
    """Train a model on a data set into the run folder ``out``, or resume the run there.

    Settings resolve as :func:`fhnn.training.settings.resolve` says: defaults < plan < what the
    data imply < ``config_file`` < ``settings`` and the dedicated arguments. A run in ``out``
    resumes with its stored settings; others are refused (``extend`` allows more Adam steps).

    Args:
        data: a data set, or its path (HDF5); one in memory is written to ``out/data.h5``.
        out: the run folder (an ensemble's folder with ``seeds`` > 1).
        config: a whole configuration: every one of its settings counts as given.
        plan: a plan of :data:`fhnn.PLANS` (``None``: the default plan for the data).
        seeds: train an ensemble of this many members (``seed`` … ``seed + seeds − 1``), each on
            its own Bayesian bootstrap of the training trajectories.
        settings: settings by dotted name, e.g. ``{"train.steps": 2000}``.
        config_file: a TOML or JSON settings file.
        model: the model kind, one of :data:`fhnn.MODELS`.
        ablation, steps, seed, max_time: ``model.ablation``, ``train.steps`` (Adam steps),
            ``train.seed``, ``train.max_time`` (the whole call's time budget [s], 0: none).
        extend: continue a run for more Adam steps (``steps`` larger than its own).
        progress: progress on the terminal (``False``: none; or a :class:`~fhnn.api.report.Reporter`).
        started: when the time budget starts (``time.monotonic()``; default: this call).

    Returns:
        The trained :class:`~fhnn.api.fit.Fit`.

    Raises:
        ConfigError: a bad setting, or a folder holding a run started with other settings.
        DataFormatError: unreadable or untrainable data.
        Interrupted: Ctrl-C; the runs keep their last checkpoints.
    """
    began = time.monotonic() if started is None else started  # the budget counts the whole command
    say = reporter(progress)
    if seeds is not None and seeds < 1:
        raise ConfigError(f"--seeds must be >= 1, got {seeds}")
    explicit = flatten(config.to_dict()) if config is not None else {}
    explicit.update(settings or {})
    given = given_settings(
        explicit,
        config_file,
        {
            "kind": ("--model", model),
            "model.ablation": ("--ablation", ablation),
            "train.steps": ("--steps", steps),
            "train.seed": ("--seed", seed),
            "train.max_time": ("--max-time", max_time),
        },
    )
    check_settings(given, plan)
    out = Path(out)
    check_new_folder(out)
    dataset = data if isinstance(data, Dataset) else read_dataset(data)
    stored_seeds = read_seeds(out) if is_ensemble(out) else None
    fresh = not (out / "run.json").exists() and stored_seeds is None
    res = resolve(dataset, given, plan=plan, fresh=fresh, source=source_name(data))
    settings_ = dict(res.settings)
    if seeds is None and stored_seeds is not None:
        seeds = len(stored_seeds)
        settings_.setdefault("train.seed", stored_seeds[0])
    if seeds == 1 and stored_seeds is not None:
        raise ConfigError(f"{out} holds an ensemble; resume it without --seeds, or train into a new folder")
    path = _data_file(data, out, fresh)
    if seeds is None or seeds == 1:
        run = open_run(out, settings_, res.config, dataset, path, extend=extend, say=say)
        budget = Budget.of(run.train_config, start=began)
        train_runs([run], [""], dataset, say=say, notes=res.notes, budget=budget)
        return Fit([run], dataset, out)
    if "train.bootstrap" not in given:  # an ensemble's spread should hold the sampling noise
        settings_["train.bootstrap"] = True
    res = Resolution(res.kind, settings_, res.start, res.implied, res.config, res.notes)
    base = int(settings_.get("train.seed", 0))
    members = list(range(base, base + seeds))
    runs = []
    for seed_k, folder in zip(members, start_ensemble(out, members), strict=True):
        member, member_config = res.member(seed_k)
        runs.append(open_run(folder, member, member_config, dataset, path, extend=extend, say=say))
    labels = [f"seed {s} ({k + 1}/{seeds}) " for k, s in enumerate(members)]
    budget = Budget.of(runs[0].train_config, start=began)
    train_runs(runs, labels, dataset, say=say, notes=res.notes, budget=budget)
    say.result(f"ensemble of {seeds} runs (seeds {members[0]}–{members[-1]}) in {out}")
    return Fit(runs, dataset, out)


def _data_file(data: Dataset | str | os.PathLike[str], out: Path, fresh: bool) -> Path:
    """The file the runs in ``out`` record as their data: ``data``'s path, or, for a data set in
    memory, ``out/DATA_FILE`` (written for a new run, so that :func:`fhnn.load` finds it)."""
    if not isinstance(data, Dataset):
        return Path(data)
    path = out / DATA_FILE
    if fresh:
        out.mkdir(exist_ok=True)
        write_dataset(data, path)
    elif not path.is_file():
        raise ConfigError(f"{out} holds runs trained on a data set file; pass that file's path")
    return path


def open_run(
    out: Path,
    settings: dict[str, Any],
    config: RunConfig,
    dataset: Dataset,
    data: Path,
    *,
    extend: bool,
    say: Reporter,
) -> Run:
    """The run in ``out`` to train: created, or loaded to be resumed.

    A loaded run's stored settings must match ``settings`` (``extend`` allows more Adam steps);
    a finished run is said so and returned as it is.

    Raises:
        ConfigError: a run started with other settings, or ``extend`` where no run is.
    """
    kind = str(settings.get("kind", "fhnn"))
    if (out / "run.json").exists():
        run = Run.load(out, expect_model=kind if "kind" in settings else None)
        # the time budget is the command's, not the run's: this command's, or none
        run.config = run.config.with_settings({"train.max_time": settings.get("train.max_time", 0.0)})
        continued = run.continue_cut()
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
        state = run.state
        assert state is not None
        if run.finished:
            if state.stopped is not None:
                say.warn(stopped_text(run))
            say.result(
                f"{out} has finished training ({run.ran()}); nothing "
                "to do. To train further, give a larger --steps with --extend.",
                always=True,
            )
        elif continued is not None:
            say.warn(f"resuming {out}: {continued}")
        else:
            say.warn(f"resuming {out} from step {state.step}")
        return run
    if extend:
        raise ConfigError(f"--extend continues an existing run, and {out} holds none")
    return Run.create(out, dataset, config, data_path=data)


def windowless_note(run: Run, dataset: Dataset) -> list[str]:
    """A note where train or val trajectories are too short for ``run``'s training windows."""
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


def train_runs(
    runs: list[Run],
    labels: list[str],
    dataset: Dataset,
    *,
    say: Reporter,
    notes: list[str],
    budget: Budget | None = None,
) -> None:
    """Train the unfinished ``runs`` (an ensemble's Adam phases as one program), a progress bar
    each (``labels[j]`` before its phase), then say how each ended; ``notes`` are said once the
    data are checked against the runs. ``budget``: the command's time budget, shared by the runs
    (default: ``train.max_time`` from now).

    Raises:
        ConfigError: data too short for the training windows.
        Interrupted: Ctrl-C or SIGTERM; each run keeps its last checkpoint.
    """
    todo = [(run, label) for run, label in zip(runs, labels, strict=True) if not run.finished]
    if not todo:
        return
    for run, _ in todo:  # before the progress bar: a data set too short for the windows is one line
        run.check_windows(dataset)
    for note in [*notes, *windowless_note(todo[0][0], dataset)]:
        say.note(note)
    columns = (
        TextColumn("{task.fields[label]}{task.fields[phase]:9s}"),
        BarColumn(bar_width=20),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[losses]}", table_column=Column(no_wrap=True, overflow="ellipsis")),
    )
    with say.progress(*columns) as bar:
        callbacks, on_steps = [], []
        for run, label in todo:
            cfg = run.train_config
            total = cfg.steps + cfg.lbfgs_steps + cfg.track_steps
            done = run.state.step if run.state else 0
            task = bar.add_task(
                "train", total=total, completed=done, losses="", phase="compiling", label=label
            )
            callbacks.append(_progress_callback(bar, task))
            on_steps.append(_step_callback(bar, task))
        try:
            if len(todo) == 1:
                todo[0][0].train(dataset, callback=callbacks[0], on_step=on_steps[0], budget=budget)
            else:
                members = [run for run, _ in todo]
                train_members(members, dataset, callbacks=callbacks, on_steps=on_steps, budget=budget)
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
        _say_ended(run, say)


def _say_ended(run: Run, say: Reporter) -> None:
    """How ``run``'s training ended: a guard's stop (even when quiet), the warm-up, the result."""
    state = run.state
    assert state is not None
    if state.stopped is not None:
        say.warn(stopped_text(run))
    decided = [r for r in state.history if "warmup" in r]
    if decided:
        say.note(warmup_text(decided[-1], run))
    more = "" if run.finished else " (cut by the time budget: run the same command again to continue)"
    say.result(
        f"trained {run.kind}: {run.ran()}{more}; best validation loss "
        f"{state.best_val:.3e}; saved to {run.folder}"
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


def _step_callback(bar: Progress, task: Any) -> Any:
    """A step callback that moves ``task`` (at most every 0.1 s, and at each new phase)."""
    told = {"phase": "", "at": 0.0}

    def stepped(phase: str, step: int) -> None:
        fault_point(phase, step)
        now = time.monotonic()
        if phase != told["phase"] or now - told["at"] >= 0.1:
            told.update(phase=phase, at=now)
            bar.update(task, completed=step, phase=PHASE_NAMES.get(phase, phase))

    return stepped


def warmup_text(record: dict[str, Any], run: Run) -> str:
    """What the warm-up's validation loss decided (``train.warmup_accept``)."""
    train = run.train_config
    val, accept = record["val_total"], train.warmup_accept
    if record["warmup"] == "kept":
        return f"warm-up kept (validation loss {val:.2e} <= {accept:g}): Adam skipped, polished from it"
    return (
        f"warm-up discarded at iteration {record['iteration']} of {train.warmup_steps} (validation loss "
        f"{val:.2e} > {accept:g}: the linear far field does not explain this flow); Adam started from "
        "the initial model"
    )
