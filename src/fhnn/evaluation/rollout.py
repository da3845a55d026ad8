"""High-accuracy rollouts of a model from each test trajectory's first state (SPEC §5).

The model is integrated with adaptive Dopri8 whose steps land on every sample time (no
interpolation error), with each trajectory's own ``F_ext(t)``. Divergence — a non-finite state, a
state beyond ``BLOW_UP`` times the initial scale, or a solver failure — is reported per trajectory,
never dropped silently.
"""

from __future__ import annotations

from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import Split
from fhnn.models.base import AbstractVectorField
from fhnn.physics.actuation import actuation_force
from fhnn.physics.integrators import adaptive_solve

#: Default rollout tolerance; its real error is checked by a test against a 100× tighter solve.
ROLLOUT_TOL = 1e-10
#: A rollout whose state exceeds this multiple of the largest initial-state component (at least
#: 1) has blown up; it stops there and is reported as diverged.
BLOW_UP = 1e3
#: Step budget per sample interval: a rollout needing more (a stiff, e.g. LNN, model) counts as a
#: solver failure and is reported as diverged. Well-posed models take about one step per interval.
STEPS_PER_SAMPLE = 20


@dataclass(frozen=True)
class Rollout:
    """Predicted states ``(N, T, 4)`` at times ``t`` ``(T,)``; ``ok`` ``(N,)`` false where diverged."""

    t: np.ndarray
    states: np.ndarray
    ok: np.ndarray


@eqx.filter_jit
def _rollout_batch(
    model: AbstractVectorField,
    y0: jax.Array,
    act: jax.Array,
    ts: jax.Array,
    rtol: float,
    atol: float,
    max_steps: int,
    bound: jax.Array,
) -> tuple[jax.Array, jax.Array]:
    def one(s0: jax.Array, a: jax.Array) -> tuple[jax.Array, jax.Array]:
        return adaptive_solve(
            lambda s, t: model(s, t, actuation_force(a, t)),
            s0,
            ts,
            rtol=rtol,
            atol=atol,
            dense=False,
            max_steps=max_steps,
            bound=bound,
        )

    return jax.vmap(one)(y0, act)


def rollout(
    model: AbstractVectorField,
    split: Split,
    *,
    until: float | None = None,
    rtol: float = ROLLOUT_TOL,
    atol: float = ROLLOUT_TOL,
    from_clean: bool = True,
    scales: tuple | None = None,
) -> Rollout:
    """Integrate ``model`` from every trajectory's state at ``t = 0`` up to ``until`` [s].

    Args:
        model: the vector field.
        split: trajectories (their first states and forcing).
        until: last time [s]; default: the trajectories' end.
        rtol, atol: integrator tolerances.
        from_clean: start from the clean first state (SPEC §5) rather than the observed one.
        scales: training loss scales, needed by discrete models (DHN) to fit a trajectory's code.
    """
    if hasattr(model, "autoregressive_rollout"):  # discrete models (DHN) roll themselves out
        if scales is None:
            raise ValueError("a discrete model's rollout needs the training loss scales")
        t, states, ok = model.autoregressive_rollout(split, until, scales)
        return Rollout(t=np.asarray(t), states=np.asarray(states), ok=np.asarray(ok))
    t = split.t if until is None else split.t[: np.searchsorted(split.t, until - 1e-9) + 1]
    y0 = (split.states_clean if from_clean else split.states)[:, 0]
    max_steps = STEPS_PER_SAMPLE * (t.size - 1) + 1000
    bound = jnp.asarray(BLOW_UP * max(1.0, float(np.max(np.abs(y0)))))
    ys, ok = _rollout_batch(
        model, jnp.asarray(y0), jnp.asarray(split.actuation), jnp.asarray(t), rtol, atol, max_steps, bound
    )
    ys = np.asarray(ys)
    ok = np.asarray(ok) & np.all(np.isfinite(ys), axis=(1, 2))
    return Rollout(t=np.asarray(t), states=ys, ok=ok)
