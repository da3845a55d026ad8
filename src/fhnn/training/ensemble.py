"""An ensemble: runs of one configuration that differ only in their seed, kept in one folder.

Folder layout (``fhnn train DATA -o OUT --seeds N``)::

    OUT/ensemble.json   format "fhnn-ensemble", format_version, the members' seeds
    OUT/seed-S/         a run folder (:class:`fhnn.training.run.Run`) per seed S

The members are trained one after another in one process: they have the same shapes and
configuration, so the first member's compiled programs serve every other member (nothing is
traced or compiled again), and each stays an ordinary run that can be resumed, inspected or
evaluated on its own. Training them as one ``vmap``-ed program was measured on the 2-core CPU
(``benchmarks/training_speed.py``, three members): 1.84× the throughput of sequential Adam steps
for the default plan's step (0.76× for the step with every loss term and the penalty), which
would shorten only the Adam phase — about half of a default-plan run on ``steady_vortex``, none
of one on ``solid_body_vortex``, whose plan is quasi-Newton only.

The spread of the members is what ``fhnn inspect`` and ``fhnn predict`` report as an interval:
the 5th–95th percentile over the members (:data:`INTERVAL`), at each point. It measures how
much the answer depends on the initialisation and batch order, not the data's sampling noise.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from fhnn.errors import ConfigError, DataFormatError
from fhnn.files import write_atomic

ENSEMBLE_FORMAT = "fhnn-ensemble"
ENSEMBLE_FORMAT_VERSION = 1
MANIFEST = "ensemble.json"
#: Percentiles of the members an interval spans (a central 90 % interval).
INTERVAL = (5.0, 95.0)


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


def interval(values: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Median and the :data:`INTERVAL` percentiles of ``values`` over the members' ``axis``:
    ``(median, lo, hi)``, NaN where any member is NaN."""
    median = np.median(values, axis=axis)
    lo, hi = np.percentile(values, INTERVAL, axis=axis)
    return median, lo, hi


def _span(seeds: list[int]) -> str:
    return ", ".join(str(s) for s in seeds)


__all__ = [
    "INTERVAL",
    "MANIFEST",
    "interval",
    "is_ensemble",
    "member_folder",
    "member_folders",
    "read_seeds",
    "start_ensemble",
]
