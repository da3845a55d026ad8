"""Training examples cut from a split: windows of consecutive samples, and the loss scales.

A model learns from windows of ``W`` consecutive samples of one trajectory (``W = 2``: a
transition pair). :class:`LossScales` holds the per-component standard deviations that make the
derivative and one-step residuals of positions, velocities and accelerations weigh alike; the
one-step scale of ``W = 2`` windows is also what the baselines standardise their increments with.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import Split
from fhnn.errors import ConfigError

Array = jax.Array


@dataclass(frozen=True)
class Windows:
    """``W`` consecutive samples of a split, for every start ``k`` (trajectory-level windows).

    Shapes: ``s``, ``deriv`` ``(P, W, 4)``; ``t`` ``(P, W)``; ``forces`` ``(P, W, 2)`` (recorded);
    ``act`` ``(P, 2, 3, 3)``; ``traj`` ``(P,)`` (index of the trajectory in its split); ``dforce``
    ``(P, W, 2)``: the recorded forces less the sinusoids of ``act``
    (:attr:`~fhnn.data.dataset.Split.force_residual`); ``start`` ``(P,)``: the sample of its
    trajectory each window starts at (not passed to a model); ``switch`` ``(P, W)`` [s]: held
    forcing's change time in each interval (:attr:`~fhnn.data.dataset.Split.switch`), ``None``
    where the forcing is interpolated. ``W = 2`` gives transition pairs.
    """

    s: np.ndarray
    t: np.ndarray
    deriv: np.ndarray
    forces: np.ndarray
    act: np.ndarray
    traj: np.ndarray
    dforce: np.ndarray
    start: np.ndarray
    switch: np.ndarray | None = None

    #: The fields a model's loss reads (:meth:`as_jax`; ``switch`` too where it is given).
    BATCH_FIELDS = ("s", "t", "deriv", "forces", "act", "traj", "dforce")
    FIELDS = (*BATCH_FIELDS, "start", "switch")

    @staticmethod
    def check(split: Split, window: int = 2, *, skip: int = 0) -> None:
        """Raise :class:`~fhnn.errors.ConfigError` unless some trajectory of ``split`` holds a
        window of ``window`` samples starting at sample ``skip`` or later (what :meth:`of` needs;
        cheap: no window is cut). Shorter trajectories are allowed — a user's tracks come in any
        length — and give no window (:meth:`without_window` counts them)."""
        counts = split.sample_counts
        if counts.max() < skip + window:
            raise ConfigError(
                f"no trajectory has a window of {window} samples starting at sample {skip} or later "
                f"(the longest has {counts.max()} samples)"
            )

    @staticmethod
    def without_window(split: Split, window: int = 2, *, skip: int = 0) -> int:
        """How many trajectories of ``split`` hold no window of ``window`` samples starting at
        sample ``skip`` or later (fewer than ``skip + window`` samples): a loss on windows leaves
        them out."""
        return int(np.sum(split.sample_counts < skip + window))

    @classmethod
    def of(cls, split: Split, window: int = 2, *, skip: int = 0) -> Windows:
        """Every window of ``window`` consecutive real samples (padding never enters one) that
        starts at sample ``skip`` of its trajectory or later; on irregularly sampled data each
        window carries its own times."""
        cls.check(split, window, skip=skip)
        n, T = split.n_traj, split.n_times
        counts = split.sample_counts
        starts = np.arange(T - window + 1)
        idx = starts[:, None] + np.arange(window)[None, :]  # (K, W)
        inside = starts[None, :] + window <= counts[:, None]  # (N, K): inside each trajectory
        keep = (inside & (starts[None, :] >= skip)).reshape(-1)

        def cut(a: np.ndarray) -> np.ndarray:
            return a[:, idx].reshape(-1, window, *a.shape[2:])[keep]

        return cls(
            s=cut(split.states),
            t=cut(split.times),
            deriv=cut(split.derivs),
            forces=cut(split.forces),
            act=np.repeat(split.actuation, starts.size, axis=0)[keep],
            traj=np.repeat(np.arange(n), starts.size)[keep],
            dforce=cut(split.force_residual),
            start=np.tile(starts, n)[keep],
            switch=None if split.switch is None else cut(split.switch),
        )

    def __len__(self) -> int:
        return int(self.s.shape[0])

    def subset(self, idx: np.ndarray) -> Windows:
        return Windows(*(None if getattr(self, k) is None else getattr(self, k)[idx] for k in self.FIELDS))

    def as_jax(self) -> dict[str, Array]:
        out = {k: jnp.asarray(getattr(self, k)) for k in self.BATCH_FIELDS}
        if self.switch is not None:
            out["switch"] = jnp.asarray(self.switch)
        return out


@dataclass(frozen=True)
class LossScales:
    """Per-component scales of the derivative and step residuals (from the training split)."""

    deriv: np.ndarray
    step: np.ndarray

    @classmethod
    def of(cls, windows: Windows) -> LossScales:
        floor = lambda x: np.maximum(x, 1e-12)  # noqa: E731
        deriv = windows.deriv[:, 0]
        step = windows.s[:, 1] - windows.s[:, 0]
        return cls(deriv=floor(deriv.std(axis=0)), step=floor(step.std(axis=0)))
