"""High-accuracy rollouts of a model from each test trajectory's first state (docs/spec.md §5).

A continuous model (a vector field) is integrated with adaptive Dopri8 whose steps land on every
sample time (no interpolation error), with each trajectory's own ``F_ext(t)``; a discrete model
(DHN) rolls itself out step by step. Divergence — a non-finite state, a state beyond ``BLOW_UP``
times the initial scale, or a solver failure — is reported per trajectory, never dropped silently.
"""

from __future__ import annotations

from typing import Any

from fhnn.data.dataset import Split
from fhnn.models.base import BLOW_UP, ROLLOUT_TOL, STEPS_PER_SAMPLE, AbstractModel, Rollout


def rollout(model: AbstractModel, split: Split, **options: Any) -> Rollout:
    """Predict every trajectory of ``split`` from ``t = 0`` with ``model``; ``options`` (``until``
    [s], ``rtol``, ``atol``, ``from_clean``) as for :meth:`AbstractModel.rollout`."""
    return model.rollout(split, **options)


__all__ = ["BLOW_UP", "ROLLOUT_TOL", "STEPS_PER_SAMPLE", "Rollout", "rollout"]
