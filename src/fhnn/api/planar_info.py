"""What ``fhnn info`` says of a turning body's data set, with known forces or under logged
controls: where it came from, the body, the splits and the ranges its states cover."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from fhnn.data.planar import KIND, PlanarDataset, read_planar
from fhnn.data.planar_controls_file import CONTROLS_KIND, file_kind, read_controlled
from fhnn.errors import DataFormatError


def is_turning_data(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is an HDF5 file of a turning body's data set (either kind); ``False`` for
    anything else, a missing or unreadable file included."""
    try:
        return file_kind(path) in (KIND, CONTROLS_KIND)
    except DataFormatError:
        return False


def turning_info(data: PlanarDataset | str | os.PathLike[str]) -> dict[str, Any]:
    """A turning body's data set in numbers.

    Args:
        data: the data set, or its HDF5 file (with known forces or under controls).

    Returns:
        ``scenario``, ``seed``, ``controls`` (the control columns' names, or ``None`` for known
        forces), the body's ``mass`` [kg], ``inertia`` [kg·m²] and ``x_g`` [m], ``obs_noise``,
        per split the ``trajectories``, ``samples`` and the longest ``duration`` [s], and
        ``covered``: the least and largest ``x, y`` [m], ``heading`` [rad], ``u, v`` [m/s] and ``r``
        [rad/s] of the training split's states; for an import also its ``noise`` estimates and
        ``smoother``.

    Raises:
        DataFormatError: not a turning body's data set.
    """
    controls: tuple[str, ...] | None = None
    if isinstance(data, PlanarDataset):
        dataset = data
    elif file_kind(data) == CONTROLS_KIND:
        dataset, controls = read_controlled(data)
    else:
        dataset = read_planar(data)
    splits = {}
    for name, split in dataset.splits.items():
        span = split.t[np.arange(split.lengths.size), split.lengths - 1] - split.t[:, 0]
        splits[name] = {
            "trajectories": int(split.lengths.size),
            "samples": int(split.lengths.sum()),
            "duration": float(span.max()),
        }
    train = dataset.splits["train"]
    states = train.states[train.valid()]
    names = ("x", "y", "heading", "u", "v", "r")
    covered = {k: [float(states[:, i].min()), float(states[:, i].max())] for i, k in enumerate(names)}
    out: dict[str, Any] = {
        "scenario": dataset.scenario,
        "seed": dataset.seed,
        "controls": None if controls is None else list(controls),
        "mass": dataset.mass,
        "inertia": dataset.inertia,
        "x_g": dataset.x_g,
        "obs_noise": dataset.obs_noise,
        "splits": splits,
        "covered": covered,
    }
    if not dataset.has_truth:
        out |= {"noise": dataset.params.get("noise"), "smoother": dataset.params.get("smoother")}
    return out


__all__ = ["is_turning_data", "turning_info"]
