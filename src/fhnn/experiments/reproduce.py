"""``fhnn reproduce``: simulate, train, evaluate and report the whole grid (docs/spec.md §6).

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
from fhnn.runtime import __version__, default_cache_dir, provenance, source_digest

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


class _Schedule:
    """The data sets and training jobs a reproduction still has to run, as tasks: each data set's
    jobs are scheduled as soon as it exists; finished tasks' files are written under ``out``.

    Args:
        out: the reproduction folder.
        datasets, jobs: all of the reproduction's data sets and training jobs.
        ray_address: Ray workers get and return data sets as bytes; local ones use the files.
        report: told ``("jobs", done, total, label)`` as tasks finish.
    """

    def __init__(
        self,
        out: Path,
        datasets: list[DataJob],
        jobs: list[ModelJob],
        ray_address: str | None,
        report: ProgressFn,
    ) -> None:
        self.out, self.datasets, self.ray, self.report = out, datasets, bool(ray_address), report
        self.by_id: dict[str, DataJob] = {d.id: d for d in datasets}
        self.jobs_by_id: dict[str, ModelJob] = {j.id: j for j in jobs}
        self.todo = [d for d in datasets if not (out / "data" / d.filename).is_file()]
        self.todo_jobs = [j for j in jobs if not (out / "jobs" / j.id / "result.json").is_file()]
        self.total = len(self.todo) + len(self.todo_jobs)
        self.done = 0
        self.data_bytes: dict[str, bytes] = {}
        self.groups: dict[str, list[ModelJob]] = {}  # a task of several jobs (seeds_together): its jobs
        cached = len(datasets) - len(self.todo) + len(jobs) - len(self.todo_jobs)
        report("jobs", 0, self.total, f"{cached} cached")

    def first(self) -> list[Task]:
        """The tasks to start with: the missing data sets, and the jobs of those that exist."""
        tasks = [self.data_task(d) for d in self.todo]
        for d in self.datasets:
            if d not in self.todo:
                tasks += self.model_tasks(d)
        return tasks

    def data_arg(self, d: DataJob) -> bytes | str:
        """How a worker gets ``d``: its path (local), or its bytes (Ray)."""
        path = self.out / "data" / d.filename
        if not self.ray:
            return str(path.resolve())
        if d.id not in self.data_bytes:
            self.data_bytes[d.id] = path.read_bytes()
        return self.data_bytes[d.id]

    def data_task(self, d: DataJob) -> Task:
        """The task that simulates ``d`` (into its file, or returning its bytes to a Ray driver)."""
        target = None if self.ray else str((self.out / "data" / d.filename).resolve())
        return Task(d.id, "data", (d.spec, target))

    def model_tasks(self, d: DataJob) -> list[Task]:
        """A task per unfinished job of ``d``, or per table cell for jobs trained together."""
        tasks: dict[object, list[ModelJob]] = {}
        for j in self.todo_jobs:
            if j.data.id == d.id:
                tasks.setdefault(j.cell if j.together else j.id, []).append(j)
        out = []
        for members in tasks.values():
            if len(members) == 1:
                out.append(Task(members[0].id, "model", (members[0].spec, self.data_arg(d), d.filename)))
            else:
                name = "+".join(j.id for j in members)
                self.groups[name] = members
                out.append(Task(name, "models", ([j.spec for j in members], self.data_arg(d), d.filename)))
        return out

    def on_done(self, task: Task, output: object) -> list[Task]:
        """Write a finished task's files; returns the tasks it makes possible."""
        self.done += 1
        if task.function == "data":
            if isinstance(output, bytes):
                write_atomic(self.out / "data" / self.by_id[task.name].filename, output)
            self.report("jobs", self.done, self.total, self.by_id[task.name].label)
            return self.model_tasks(self.by_id[task.name])
        if task.function == "models":
            assert isinstance(output, list)
            members = self.groups[task.name]
            for job, files in zip(members, output, strict=True):
                write_folder_atomic(self.out / "jobs" / job.id, files)
            self.done += len(members) - 1
            self.report("jobs", self.done, self.total, " + ".join(j.label for j in members))
            return []
        assert isinstance(output, dict)
        write_folder_atomic(self.out / "jobs" / task.name, output)
        self.report("jobs", self.done, self.total, self.jobs_by_id[task.name].label)
        return []


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
        json.dumps(
            {
                "format": FORMAT,
                "version": __version__,
                "config": config.to_dict(),
                "provenance": provenance(),
            },
            indent=1,
        ).encode(),
    )
    # the commands' compilation cache (fhnn.runtime.default_cache_dir): a job compiled by an earlier
    # reproduction, a killed one or a plain `fhnn train` of the same shapes is loaded, not compiled
    cache_dir = default_cache_dir()
    report = progress or (lambda *a: None)
    xla_flags = FAST_COMPILE_FLAGS if config.fast_compile else ""

    # 1–2. data sets, and the training jobs of each as soon as its data set exists
    schedule = _Schedule(out, datasets, jobs, ray_address, report)
    if ray_address:
        run_ray(
            schedule.first(), schedule.on_done, address=ray_address, cache_dir=cache_dir, xla_flags=xla_flags
        )
    else:
        run_local(
            schedule.first(), schedule.on_done, workers=workers, cache_dir=cache_dir, xla_flags=xla_flags
        )
    todo, todo_jobs = schedule.todo, schedule.todo_jobs

    # 3. the report, unless nothing changed since it was last built
    stamp = hashlib.sha256(
        json.dumps(
            [source_digest((".",)), config.to_dict(), sorted(schedule.jobs_by_id)], sort_keys=True
        ).encode()
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
