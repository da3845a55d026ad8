"""Resampled data for an ensemble of turning-body models: each member trains on its own bootstrap
of the training trajectories, so the members' spread holds the data's sampling noise besides the
initialisation's and the batch order's (:mod:`fhnn.api.planar_ensemble` trains and reads them)."""

from __future__ import annotations

import dataclasses

import numpy as np

from fhnn.data.planar import PlanarDataset, PlanarSplit

#: The stream of :func:`bootstrap_planar`'s generator beside the member's seed (apart from the
#: weights' initialisation, which :class:`~fhnn.training.planar.PlanarTrainConfig`'s seed draws).
PLANAR_BOOTSTRAP_STREAM = 7


def bootstrap_indices(n_traj: int, seed: int) -> np.ndarray:
    """``n_traj`` trajectory indices drawn with replacement from ``range(n_traj)`` by ``seed``,
    sorted, ``(n_traj,)`` ints (a trajectory may appear several times or not at all).

    Raises:
        ValueError: ``n_traj`` is below 2 (one trajectory has no other to resample).
    """
    if n_traj < 2:
        raise ValueError(f"a bootstrap needs at least 2 training trajectories, got {n_traj}")
    rng = np.random.default_rng([seed, PLANAR_BOOTSTRAP_STREAM])
    return np.sort(rng.integers(0, n_traj, n_traj))


def bootstrap_planar(dataset: PlanarDataset, seed: int) -> PlanarDataset:
    """``dataset`` with its training split replaced by a bootstrap of its trajectories
    (:func:`bootstrap_indices`); the validation and test splits, the body and the truth are
    unchanged.

    Raises:
        ValueError: the training split holds fewer than 2 trajectories.
    """
    train = dataset.splits["train"]
    pick = bootstrap_indices(train.t.shape[0], seed)
    resampled = PlanarSplit(**{f.name: getattr(train, f.name)[pick] for f in dataclasses.fields(PlanarSplit)})
    return dataclasses.replace(dataset, splits={**dataset.splits, "train": resampled})


__all__ = ["PLANAR_BOOTSTRAP_STREAM", "bootstrap_indices", "bootstrap_planar"]
