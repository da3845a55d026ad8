"""An ensemble: runs of one configuration that differ only in their seed, kept in one folder.

Folder layout (``fhnn train DATA -o OUT --seeds N``)::

    OUT/ensemble.json   format "fhnn-ensemble", format_version, the members' seeds
    OUT/seed-S/         a run folder (:class:`fhnn.training.run.Run`) per seed S

The members are trained in one process by :func:`train_members`: their warm-ups one after
another, their Adam phases together as one ``vmap``-ed program per step
(:func:`~fhnn.training.together.run_together`), their L-BFGS polishes one after another. They have
the same shapes and configuration, so the first member's compiled programs serve every other
member, and each stays an ordinary run that can be resumed, inspected or evaluated on its own.
Whether training the members together pays depends on the machine (design note
``docs/design/plans.md``).

``fhnn train --seeds N`` trains each member on its own Bayesian bootstrap of the training
trajectories (``train.bootstrap``: every trajectory weighted by a random positive weight of mean
1, :func:`~fhnn.training.sampling.bootstrap_weights`; ``--set train.bootstrap=false`` trains all
on the same data), so the members' spread holds the data's sampling noise besides the
initialisation's and the batch order's. ``fhnn inspect`` reports it as a 90 % interval at each
point (:func:`interval`): the members' mean ± ``t(0.95; N−1) · s · √(1 + 1/N)``, ``s`` their
standard deviation — the interval that holds a value drawn like the members with 90 %
probability, which is what the truth is to a bagged estimate. ``fhnn predict``'s band
pools every member's forecasts from many start states, enough for its 5th–95th percentiles
(:data:`INTERVAL`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import write_atomic
from fhnn.models.registry import MODELS
from fhnn.training.budget import Budget
from fhnn.training.run import Run
from fhnn.training.together import can_run_together, run_together
from fhnn.training.trainer import TrainState

ENSEMBLE_FORMAT = "fhnn-ensemble"
ENSEMBLE_FORMAT_VERSION = 1
MANIFEST = "ensemble.json"
#: Percentiles of a pooled sample that a band spans (a central 90 % band; ``fhnn predict``).
INTERVAL = (5.0, 95.0)
#: The probability an ensemble's :func:`interval` is built to hold.
LEVEL = 0.9


def member_folder(folder: str | os.PathLike[str], seed: int) -> Path:
    """The run folder of the member with ``seed``."""
    return Path(folder) / f"seed-{seed}"


def is_ensemble(folder: str | os.PathLike[str]) -> bool:
    """Whether ``folder`` holds an ensemble (its manifest)."""
    return (Path(folder) / MANIFEST).is_file()


def start_ensemble(folder: str | os.PathLike[str], seeds: list[int]) -> list[Path]:
    """Create (or check, when it exists) the ensemble ``folder`` of ``seeds``; returns the member
    folders. A folder holding a single run, or an ensemble of other seeds, is refused."""
    folder = Path(folder)
    if len(seeds) < 2:
        raise ConfigError(f"an ensemble needs at least 2 seeds, got {len(seeds)}")
    if (folder / "run.json").exists():
        raise ConfigError(
            f"{folder} holds a single run, not an ensemble; train the ensemble into a new folder"
        )
    if is_ensemble(folder):
        stored = read_seeds(folder)
        if stored != seeds:
            raise ConfigError(
                f"{folder} holds an ensemble of seeds {_span(stored)}, not {_span(seeds)}; rerun with "
                "its own --seed and --seeds to resume it, or train into a new folder"
            )
    else:
        folder.mkdir(exist_ok=True)
        manifest = {"format": ENSEMBLE_FORMAT, "format_version": ENSEMBLE_FORMAT_VERSION, "seeds": seeds}
        write_atomic(folder / MANIFEST, json.dumps(manifest, indent=1))
    return [member_folder(folder, s) for s in seeds]


def read_seeds(folder: str | os.PathLike[str]) -> list[int]:
    """The members' seeds from the manifest of ``folder``."""
    path = Path(folder) / MANIFEST
    try:
        info = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DataFormatError(f"{path}: not a readable ensemble manifest ({exc})") from None
    if not isinstance(info, dict) or info.get("format") != ENSEMBLE_FORMAT:
        raise DataFormatError(f"{path}: not an fhnn ensemble manifest")
    version = info.get("format_version")
    if not isinstance(version, int) or not 1 <= version <= ENSEMBLE_FORMAT_VERSION:
        raise DataFormatError(
            f"{path}: unsupported ensemble format_version {version!r} (this fhnn reads 1 to "
            f"{ENSEMBLE_FORMAT_VERSION})"
        )
    seeds = info.get("seeds")
    if not isinstance(seeds, list) or len(seeds) < 2 or not all(isinstance(s, int) for s in seeds):
        raise DataFormatError(f"{path}: 'seeds' must list at least 2 integer seeds")
    return seeds


def member_folders(folder: str | os.PathLike[str]) -> list[Path]:
    """The run folders of the ensemble in ``folder``; a member not trained yet is a one-line
    :class:`DataFormatError` saying how to finish it."""
    folders = [member_folder(folder, s) for s in read_seeds(folder)]
    missing = [f.name for f in folders if not (f / "run.json").is_file()]
    if missing:
        raise DataFormatError(
            f"{folder}: member(s) {', '.join(missing)} not trained yet; run the same fhnn train command "
            "again to finish the ensemble"
        )
    return folders


Callback = Callable[[TrainState, dict[str, float]], None]


def train_members(
    runs: list[Run],
    dataset: Dataset,
    *,
    callbacks: list[Callback | None] | None = None,
    on_steps: list[Callable[[str, int], None] | None] | None = None,
    together: bool = True,
    budget: Budget | None = None,
) -> None:
    """Train (or resume) the members ``runs`` of an ensemble on ``dataset`` to the end of every
    phase, checkpointing each as :meth:`Run.train` does (``callbacks[j]`` at member ``j``'s
    records, ``on_steps[j]`` at its steps). With ``together`` (and members that allow it:
    :func:`~fhnn.training.together.can_run_together`) their Adam phases run as one program;
    otherwise, or for a fitted kind, each member trains on its own, one after another. The members
    share one time budget (``budget``, default ``train.max_time`` from now): a phase they run
    one after another gives each an equal share of what is left to its deadline
    (:meth:`~fhnn.training.budget.Budget.turn`)."""
    n = len(runs)
    callbacks = callbacks or [None] * n
    on_steps = on_steps or [None] * n
    budget = budget if budget is not None else Budget.of(runs[0].train_config)
    if not together or any(MODELS[r.kind].fit is not None for r in runs):
        for j, (run, callback, on_step) in enumerate(zip(runs, callbacks, on_steps, strict=True)):
            run.train(dataset, callback=callback, on_step=on_step, budget=budget.share(n - j))
        return
    trainers = [run.trainer(dataset, on_step, budget) for run, on_step in zip(runs, on_steps, strict=True)]
    for j, run in enumerate(runs):
        with budget.turn("warmup", n - j):
            run.begin(trainers[j], callback=callbacks[j])
    states: list[TrainState] = [run.state for run in runs]  # type: ignore[misc]
    waiting = [j for j, run in enumerate(runs) if states[j].step < run.train_config.steps]
    if can_run_together([trainers[j] for j in waiting], [states[j] for j in waiting]):
        run_together(
            [trainers[j] for j in waiting],
            [states[j] for j in waiting],
            callbacks=[runs[j].saving(callbacks[j], True) for j in waiting],
            checkpoints=[lambda state, run=runs[j]: run.save() for j in waiting],
            checkpoint_seconds=min(runs[j].checkpoint_seconds for j in waiting),
        )
    else:
        for k, j in enumerate(waiting):
            with budget.turn("adam", len(waiting) - k):
                runs[j].adam(trainers[j], callback=callbacks[j])
    for j, run in enumerate(runs):
        with budget.turn("lbfgs", n - j):
            run.finish(trainers[j], callback=callbacks[j])


def interval(values: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The members' median and a :data:`LEVEL` interval from ``values`` over the members' ``axis``
    (``N ≥ 2`` of them): ``(median, lo, hi)`` with ``lo, hi = mean ∓ t · s · √(1 + 1/N)``, ``s``
    the members' sample standard deviation and ``t`` Student's ``(1 + LEVEL)/2`` quantile with
    ``N − 1`` degrees of freedom (the prediction interval of one more draw from a normal law whose
    mean and spread are estimated from ``N``: for bootstrap members it is the interval of the
    truth about their bagged mean); NaN where any member is NaN."""
    from scipy.stats import t as student_t

    n = values.shape[axis]
    if n < 2:
        raise ValueError(f"an interval needs at least 2 members, got {n}")
    median = np.median(values, axis=axis)
    mean = np.mean(values, axis=axis)
    half = student_t.ppf(0.5 + LEVEL / 2, n - 1) * np.std(values, axis=axis, ddof=1) * np.sqrt(1 + 1 / n)
    return median, mean - half, mean + half


def _span(seeds: list[int]) -> str:
    return ", ".join(str(s) for s in seeds)


__all__ = [
    "INTERVAL",
    "LEVEL",
    "MANIFEST",
    "interval",
    "is_ensemble",
    "member_folder",
    "member_folders",
    "read_seeds",
    "start_ensemble",
    "train_members",
]
