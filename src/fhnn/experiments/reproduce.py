"""``fhnn reproduce``: simulate, train, evaluate and report the whole grid (SPEC §6).

Three phases, each skipping what is already done:

1. data jobs → ``OUT/data/<label>-<hash>.h5``;
2. model jobs → ``OUT/jobs/<label>-<hash>/`` (``result.json``, ``rollouts.npz``, ``run/``), written
   into a temporary folder and renamed, so a folder exists only when its job finished; a data
   set's model jobs are queued as soon as that data set exists, so phases 1 and 2 overlap (with
   ``seeds_together`` the unfinished seeds of a table cell are one task, each still its own folder);
3. the report (tables, figures, ``report.md``, ``index.html``), rebuilt only when the set of
   results or the configuration changed (``OUT/report.stamp``).

An interrupted run therefore resumes where it stopped, and a second run with nothing changed
does nothing.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from fhnn.errors import ConfigError, DataFormatError
from fhnn.experiments.executors import (
    FAST_COMPILE_FLAGS,
    Task,
    check_workers,
    default_workers,
    run_local,
    run_ray,
)
from fhnn.experiments.grid import DataJob, ModelJob, ReproduceConfig, build_grid
from fhnn.experiments.report import build_report
from fhnn.files import check_new_folder, folder_lock, write_atomic, write_folder_atomic
from fhnn.runtime import __version__, default_cache_dir, source_digest

FORMAT = "fhnn-reproduction"
#: ``progress(phase, done, total, last)``: phase "jobs" (data sets and training jobs still to do)
#: or "report"; ``last`` the label of the job that just finished (at the start: how many are cached).
ProgressFn = Callable[[str, int, int, str], None]


@dataclass(frozen=True)
class Summary:
    """What a call of :func:`reproduce` did."""

    out: Path
    data_total: int
    data_run: int
    jobs_total: int
    jobs_run: int
    report_built: bool
    seconds: float


def check_output_folder(out: Path) -> None:
    """``out`` may be new, empty, or a reproduction folder; anything else is refused."""
    try:
        check_new_folder(out)
    except DataFormatError as exc:  # an option's value, not a data file: a configuration error
        raise ConfigError(str(exc)) from None
    held = [p for p in out.iterdir() if p.name != ".lock"] if out.is_dir() else []
    if held and not (out / "reproduce.json").is_file():
        raise ConfigError(f"output folder '{out}' is not empty and holds no reproduction (no reproduce.json)")


def reproduce(
    config: ReproduceConfig,
    out: Path,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: ProgressFn | None = None,
) -> Summary:
    """Run every job the report needs that is not yet done, then build the report. A second
    process on the same folder is refused while this one runs (:func:`fhnn.files.folder_lock`)."""
    started = time.perf_counter()
    out = Path(out)
    check_output_folder(out)
    workers = default_workers() if workers is None else workers
    check_workers(workers)
    datasets, jobs = build_grid(config)
    out.mkdir(exist_ok=True)
    with folder_lock(out, "fhnn reproduce"):
        return _reproduce(config, out, datasets, jobs, workers, ray_address, progress, started)


def _reproduce(
    config: ReproduceConfig,
    out: Path,
    datasets: list[DataJob],
    jobs: list[ModelJob],
    workers: int,
    ray_address: str | None,
    progress: ProgressFn | None,
    started: float,
) -> Summary:
    for stale in out.glob("jobs/.*.tmp"):  # the temporary folder of a job a kill interrupted
        shutil.rmtree(stale, ignore_errors=True)
    for sub in ("data", "jobs"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    write_atomic(
        out / "reproduce.json",
        json.dumps({"format": FORMAT, "version": __version__, "config": config.to_dict()}, indent=1).encode(),
    )
    # the commands' compilation cache (fhnn.runtime.default_cache_dir): a job compiled by an earlier
    # reproduction, a killed one or a plain `fhnn train` of the same shapes is loaded, not compiled
    cache_dir = default_cache_dir()
    report = progress or (lambda *a: None)
    xla_flags = FAST_COMPILE_FLAGS if config.fast_compile else ""

    def run(tasks: list[Task], on_done: Callable[[Task, object], None]) -> None:
        if ray_address:
            run_ray(tasks, on_done, address=ray_address, cache_dir=cache_dir, xla_flags=xla_flags)
        else:
            run_local(tasks, on_done, workers=workers, cache_dir=cache_dir, xla_flags=xla_flags)

    # 1–2. data sets, and the training jobs of each as soon as its data set exists
    by_id: dict[str, DataJob] = {d.id: d for d in datasets}
    jobs_by_id: dict[str, ModelJob] = {j.id: j for j in jobs}
    todo = [d for d in datasets if not (out / "data" / d.filename).is_file()]
    todo_jobs = [j for j in jobs if not (out / "jobs" / j.id / "result.json").is_file()]
    total = len(todo) + len(todo_jobs)
    done = 0
    report("jobs", done, total, f"{len(datasets) - len(todo) + len(jobs) - len(todo_jobs)} cached")
    # local workers read and write the data sets in place; Ray workers get and return bytes
    data_bytes: dict[str, bytes] = {}

    def data_arg(d: DataJob) -> bytes | str:
        path = out / "data" / d.filename
        if not ray_address:
            return str(path.resolve())
        if d.id not in data_bytes:
            data_bytes[d.id] = path.read_bytes()
        return data_bytes[d.id]

    groups: dict[str, list[ModelJob]] = {}  # a task of several jobs (seeds_together): its jobs

    def model_tasks(d: DataJob) -> list[Task]:
        """A task per unfinished job of ``d``, or per table cell for jobs trained together."""
        tasks: dict[object, list[ModelJob]] = {}
        for j in todo_jobs:
            if j.data.id == d.id:
                tasks.setdefault(j.cell if j.together else j.id, []).append(j)
        out = []
        for members in tasks.values():
            if len(members) == 1:
                out.append(Task(members[0].id, "model", (members[0].spec, data_arg(d), d.filename)))
            else:
                name = "+".join(j.id for j in members)
                groups[name] = members
                out.append(Task(name, "models", ([j.spec for j in members], data_arg(d), d.filename)))
        return out

    def on_done(task: Task, output: object) -> list[Task]:
        nonlocal done
        done += 1
        if task.function == "data":
            if isinstance(output, bytes):
                write_atomic(out / "data" / by_id[task.name].filename, output)
            report("jobs", done, total, by_id[task.name].label)
            return model_tasks(by_id[task.name])
        if task.function == "models":
            assert isinstance(output, list)
            members = groups[task.name]
            for job, files in zip(members, output, strict=True):
                write_folder_atomic(out / "jobs" / job.id, files)
            done += len(members) - 1
            report("jobs", done, total, " + ".join(j.label for j in members))
            return []
        assert isinstance(output, dict)
        write_folder_atomic(out / "jobs" / task.name, output)
        report("jobs", done, total, jobs_by_id[task.name].label)
        return []

    def data_task(d: DataJob) -> Task:
        target = None if ray_address else str((out / "data" / d.filename).resolve())
        return Task(d.id, "data", (d.spec, target))

    first = [data_task(d) for d in todo]
    for d in datasets:
        if d not in todo:
            first += model_tasks(d)
    run(first, on_done)

    # 3. the report, unless nothing changed since it was last built
    stamp = hashlib.sha256(
        json.dumps([source_digest((".",)), config.to_dict(), sorted(jobs_by_id)], sort_keys=True).encode()
    ).hexdigest()
    stamp_path = out / "report.stamp"
    fresh = (
        not todo_jobs
        and not todo
        and stamp_path.is_file()
        and stamp_path.read_text() == stamp
        and (out / "index.html").is_file()
    )
    if not fresh:
        report("report", 0, 1, "")
        results = {j.id: json.loads((out / "jobs" / j.id / "result.json").read_text()) for j in jobs}
        build_report(out, config, jobs, results, wall_seconds=time.perf_counter() - started)
        write_atomic(stamp_path, stamp.encode())
        report("report", 1, 1, "index.html")
    return Summary(
        out=out,
        data_total=len(datasets),
        data_run=len(todo),
        jobs_total=len(jobs),
        jobs_run=len(todo_jobs),
        report_built=not fresh,
        seconds=time.perf_counter() - started,
    )
