"""High-accuracy rollouts of a model from each test trajectory's first state (SPEC §5).

A continuous model (a vector field) is integrated with adaptive Dopri8 whose steps land on every
sample time (no interpolation error), with each trajectory's own ``F_ext(t)``; a discrete model
(DHN) rolls itself out step by step. Divergence — a non-finite state, a state beyond ``BLOW_UP``
times the initial scale, or a solver failure — is reported per trajectory, never dropped silently.
"""

from __future__ import annotations

from fhnn.data.dataset import Split
from fhnn.models.base import BLOW_UP, ROLLOUT_TOL, STEPS_PER_SAMPLE, AbstractModel, Rollout


def rollout(
    model: AbstractModel,
    split: Split,
    *,
    until: float | None = None,
    rtol: float = ROLLOUT_TOL,
    atol: float = ROLLOUT_TOL,
    from_clean: bool = True,
) -> Rollout:
    """Predict every trajectory of ``split`` from ``t = 0`` up to ``until`` [s] (default: the end).

    Args:
        model: any model (:meth:`AbstractModel.rollout`).
        split: trajectories (their first states and forcing).
        until: last time [s]; default: the trajectories' end.
        rtol, atol: integrator tolerances (continuous models).
        from_clean: start from the clean first state (SPEC §5) rather than the observed one.
    """
    return model.rollout(split, until, rtol=rtol, atol=atol, from_clean=from_clean)


__all__ = ["BLOW_UP", "ROLLOUT_TOL", "STEPS_PER_SAMPLE", "Rollout", "rollout"]
