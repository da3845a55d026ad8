"""Which training windows a step sees: minibatches, and the weights of a Bayesian bootstrap."""

from __future__ import annotations

import jax
import numpy as np

Array = jax.Array


#: The stream of :func:`bootstrap_weights`'s generator beside the seed (apart from the others).
BOOTSTRAP_STREAM = 5


def bootstrap_weights(traj: np.ndarray, n_traj: int, seed: int) -> np.ndarray:
    """Weights ``(P,)`` of windows from trajectories ``traj`` ``(P,)`` (indices below ``n_traj``)
    under a Bayesian bootstrap of the trajectories drawn from ``seed`` (Rubin 1981): the
    trajectories' weights are ``n_traj`` times a draw from the flat Dirichlet law — positive,
    mean 1, sum ``n_traj``, each about exponentially distributed — and each window takes its
    trajectory's. Whole trajectories are weighted, not windows: neighbouring windows share samples
    and noise, so they are not independent draws.

    Unlike the classical resample (``n_traj`` draws with replacement), no trajectory is left out
    (that one drops about a third of them, and a member then extrapolates its coefficients over
    the parts of the (r, σ) range only those trajectories covered); on the own-data benchmark
    the two agree within their noise (design note ``docs/design/plans.md``)."""
    rng = np.random.default_rng([seed, BOOTSTRAP_STREAM])
    weights = n_traj * rng.dirichlet(np.ones(n_traj))
    return weights[traj]


def draw_batch(key: Array, n: int, size: int, weights: Array | None = None) -> Array:
    """``size`` indices of ``n`` windows drawn with replacement with ``key``: uniformly, or with
    probabilities in proportion to ``weights`` ``(n,)`` (≥ 0, not all 0; a window of weight 0 is
    never drawn)."""
    if weights is None:
        return jax.random.randint(key, (size,), 0, n)
    return jax.random.choice(key, n, (size,), p=weights)
