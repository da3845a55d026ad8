"""``fhnn.reproduce``: the paper's tables and figures regenerated, as ``fhnn reproduce``."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn

from fhnn.api.report import Reporter, fault_point, reporter
from fhnn.errors import Interrupted
from fhnn.experiments.executors import check_workers
from fhnn.experiments.grid import ReproduceConfig, build_grid
from fhnn.experiments.reproduce import Summary, check_output_folder
from fhnn.experiments.reproduce import reproduce as run_reproduction
from fhnn.training.settings import given_settings


def reproduce(
    out: str | os.PathLike[str] = "reproduction",
    *,
    quick: bool = False,
    seeds: int | None = None,
    steps: int | None = None,
    workers: int | None = None,
    ray: str | None = None,
    settings: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
    progress: Reporter | bool = True,
) -> Summary:
    """Regenerate the data, train every model, ablation, scenario and seed of the paper's tables,
    evaluate, and write tables, figures, ``report.md`` and ``index.html`` into ``out``. Finished
    jobs are kept: an interrupted reproduction resumes, an unchanged one does nothing.

    Args:
        out: the output folder (created; resumed if it holds a reproduction).
        quick: small data, few steps, one seed, one main scenario: the whole report in minutes.
        seeds: seeds per model (default 3; quick: 1).
        steps: Adam steps per model.
        workers: local worker processes (default: one per CPU core).
        ray: run the jobs on a Ray cluster: its address, ``"auto"`` or ``"local"``.
        settings: settings by dotted name, e.g. ``{"models": "fhnn,node"}``.
        config_file: a TOML or JSON settings file.
        progress: a progress bar (``False``: none; or a :class:`~fhnn.api.report.Reporter`).

    Returns:
        The :class:`~fhnn.experiments.reproduce.Summary` of what ran.

    Raises:
        ConfigError: a bad setting or output folder.
        Interrupted: Ctrl-C; finished jobs are kept.
    """
    given = given_settings(
        settings, config_file, {"seeds": ("--seeds", seeds), "train.steps": ("--steps", steps)}
    )
    config = ReproduceConfig.quick(given) if quick else ReproduceConfig().with_settings(given)
    if workers is not None:
        check_workers(workers)
    out = Path(out)
    check_output_folder(out)
    say = reporter(progress)
    n_data, n_jobs = (len(x) for x in build_grid(config))
    say.warn(f"reproduce: {n_data} data sets, {n_jobs} training jobs ({config.seeds} seed(s)) -> {out}")
    with say.progress(
        TextColumn("{task.fields[phase]:6s}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[last]}"),
    ) as bar:
        task = bar.add_task("reproduce", total=1, phase="", last="")

        def step(phase: str, done: int, total: int, last: str) -> None:
            bar.update(task, completed=done, total=total, phase=phase, last=last)
            fault_point(phase, done)

        try:
            return run_reproduction(config, out, workers=workers, ray_address=ray, progress=step)
        except KeyboardInterrupt:
            bar.stop()
            kept = "interrupted: finished jobs are kept; run the same command again to resume"
            raise Interrupted(kept) from None
