"""Time integration of ``ṡ = f(s, t)``.

- :func:`rk4_step` / :func:`rk4_solve`: the classical fixed-step fourth-order Runge–Kutta method,
  used by training (one step over the sampling interval); :func:`rk4_solve_held` splits each
  step where a held (step-wise) force changes.
- :func:`adaptive_solve`: Dormand–Prince 8(5,3) with adaptive steps (via Diffrax), used for ground
  truth and for evaluation rollouts. By default outputs between steps come from its dense output;
  ``dense=False`` clips steps to land on every output time instead (exact step ends, about 4× the
  steps at dt = 0.05 s). Against a scipy DOP853 solve at 1e-13 (``steady_vortex``, 20 s), the
  default tolerance 1e-12 errs by 6e-11 m with dense output; clipped steps at 1e-10 by 7e-12.

``f`` is any callable ``f(s, t) -> ṡ`` on one state; batch with :func:`jax.vmap`.
:func:`solve_forced_batch` integrates many forced trajectories at once (simulation and rollouts).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.physics.actuation import forcing

Array = jax.Array
VectorField = Callable[[Array, Array], Array]


def rk4_step(f: VectorField, s: Array, t: Array, dt: Array, k1: Array | None = None) -> Array:
    """One classical RK4 step of size ``dt`` from ``(s, t)``; ``k1``: ``f(s, t)`` when the caller
    has it already (a loss on both ``f(s, t)`` and the step then traces ``f`` there once).

    The four stages stay unrolled so that XLA fuses across them (a ``lax.scan`` over stages 2–4
    ran the Adam step 22 % slower for 4 % faster compilation, ``benchmarks/training_speed.py``)."""
    half = 0.5 * dt
    if k1 is None:
        k1 = f(s, t)
    k2 = f(s + half * k1, t + half)
    k3 = f(s + half * k2, t + half)
    k4 = f(s + dt * k3, t + dt)
    return s + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def rk4_solve(f: VectorField, s0: Array, ts: Array) -> Array:
    """RK4 over the grid ``ts`` (shape ``(T,)``), one step per interval; returns ``(T, *s0.shape)``."""

    def body(s: Array, interval: tuple[Array, Array]) -> tuple[Array, Array]:
        t0, t1 = interval
        s_next = rk4_step(f, s, t0, t1 - t0)
        return s_next, s_next

    _, rest = jax.lax.scan(body, s0, (ts[:-1], ts[1:]))
    return jnp.concatenate([s0[None], rest], axis=0)


def rk4_solve_held(
    f: Callable[[Array, Array, Array], Array], s0: Array, ts: Array, inputs: Array, switch: Array
) -> Array:
    """RK4 over the grid ``ts`` ``(T,)`` of ``ṡ = f(s, t, u)`` under an input ``u`` that is held
    piecewise constant and changes at most once per interval: on interval ``k`` it is
    ``inputs[k]`` up to ``switch[k]`` and ``inputs[k + 1]`` from there to ``ts[k + 1]``
    (``ts[k] ≤ switch[k] ≤ ts[k + 1]``; ``switch[k] = ts[k + 1]``: no change). Each part takes
    one RK4 step (a part of length 0 leaves the state as it is), so a step never straddles the
    change. ``inputs``: ``(T, ...)``; ``switch``: ``(T,)`` (the last entry unused). Returns
    ``(T, *s0.shape)``."""

    def body(s: Array, interval: tuple[Array, ...]) -> tuple[Array, Array]:
        t0, t1, at, u0, u1 = interval
        mid = rk4_step(lambda x, tt: f(x, tt, u0), s, t0, at - t0)
        s_next = rk4_step(lambda x, tt: f(x, tt, u1), mid, at, t1 - at)
        return s_next, s_next

    _, rest = jax.lax.scan(body, s0, (ts[:-1], ts[1:], switch[:-1], inputs[:-1], inputs[1:]))
    return jnp.concatenate([s0[None], rest], axis=0)


#: Consecutive steps shorter than :data:`STALL_FRACTION` of the mean output interval after which
#: an adaptive solve stops as failed (:class:`StallGuard`).
STALL_PATIENCE = 100
#: A step shorter than this fraction of the mean output interval counts towards a stall.
STALL_FRACTION = 1e-9


class StallGuard(diffrax.AbstractAdaptiveStepSizeController):
    """Stops a solve, as failed, once ``patience`` consecutive steps (kept or rejected) were
    shorter than ``min_step``: the step size has collapsed onto a singularity of the vector field
    (seen on learned Lagrangians whose mass matrix turns singular: the time stalls at a point
    while accepted steps shrink geometrically), and the solve would otherwise spend its whole
    step budget there. Under :func:`jax.vmap` a stalled trajectory holds every other one in the
    loop, so stopping it early is what keeps a batch of rollouts cheap. A well-posed solve never
    trips it: after one short step (landing a few ULP short of an output time) the controller
    grows the step up to tenfold per step. The states before the stall are unchanged.

    Attributes:
        controller: the adaptive controller it wraps.
        min_step: steps shorter than this [s] count towards a stall.
        patience: consecutive short steps that stop the solve.
    """

    controller: diffrax.AbstractAdaptiveStepSizeController
    min_step: Array
    patience: int = eqx.field(static=True)

    @property
    def rtol(self) -> Any:
        return self.controller.rtol

    @property
    def atol(self) -> Any:
        return self.controller.atol

    @property
    def norm(self) -> Callable[[Any], Array]:
        return self.controller.norm

    def wrap(self, direction: Any) -> StallGuard:
        return eqx.tree_at(lambda c: c.controller, self, self.controller.wrap(direction))

    def init(
        self, terms: Any, t0: Any, t1: Any, y0: Any, dt0: Any, args: Any, func: Any, error_order: Any
    ) -> tuple[Any, Any]:
        t1, inner = self.controller.init(terms, t0, t1, y0, dt0, args, func, error_order)
        return t1, (jnp.asarray(0), inner)

    def adapt_step_size(  # the arguments of diffrax's controller interface
        self,
        t0: Any,
        t1: Any,
        y0: Any,
        y1_candidate: Any,
        args: Any,
        y_error: Any,
        error_order: Any,
        state: Any,
    ) -> tuple[Any, ...]:
        count, inner = state
        keep, next_t0, next_t1, jump, inner, result = self.controller.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, inner
        )
        count = jnp.where(t1 - t0 < self.min_step, count + 1, 0)
        result = diffrax.RESULTS.where(count >= self.patience, diffrax.RESULTS.dt_min_reached, result)
        return keep, next_t0, next_t1, jump, (count, inner), result


def adaptive_solve(
    f: VectorField,
    s0: Array,
    ts: Array,
    *,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    max_steps: int = 200_000,
    dense: bool = True,
    bound: float | None = None,
) -> tuple[Array, Array]:
    """Integrate from ``(s0, ts[0])`` with adaptive Dopri8, returning the state at every ``ts``.

    Args:
        f: vector field ``f(s, t)`` on one state.
        s0: initial state, shape ``(D,)``.
        ts: increasing output times [s], shape ``(T,)``.
        rtol, atol: local error tolerances of the step-size controller.
        max_steps: step budget; running out counts as a failure, and so does a stalled step
            size (:class:`StallGuard`).
        dense: interpolate outputs between steps (fast) rather than stepping onto every output
            time (most accurate).
        bound: stop, as a failure, once any component of the state exceeds this magnitude (a
            blowing-up model then fails fast instead of spending the step budget).

    Returns:
        ``(states, ok)``: states of shape ``(T, D)`` and a scalar bool that is true when the solver
        reached ``ts[-1]`` with finite states (after a failure, the states past it are not finite).
    """
    term = diffrax.ODETerm(lambda t, y, args: f(y, t))
    controller = diffrax.PIDController(rtol=rtol, atol=atol)
    if not dense:
        controller = diffrax.ClipStepSizeController(controller, step_ts=ts)
    min_step = STALL_FRACTION * (ts[-1] - ts[0]) / (ts.shape[0] - 1)
    controller = StallGuard(controller, min_step, STALL_PATIENCE)
    sol = diffrax.diffeqsolve(
        term,
        diffrax.Dopri8(),
        t0=ts[0],
        t1=ts[-1],
        dt0=None,
        y0=s0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=controller,
        max_steps=max_steps,
        throw=False,
        event=None if bound is None else diffrax.Event(lambda t, y, args, **kw: jnp.max(jnp.abs(y)) > bound),
    )
    ys = sol.ys
    ok = (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(ys))
    return ys, ok


@eqx.filter_jit
def solve_forced_batch(
    field: Callable[[Array, Array, Array], Array],
    y0: Array,
    actuation: Array,
    ts: Array,
    rtol: float,
    atol: float,
    max_steps: int = 200_000,
    bound: Array | None = None,
    residual: Array | None = None,
) -> tuple[Array, Array]:
    """Many trajectories of a forced system ``ṡ = field(s, t, F(t))``, stepping onto every time.

    Args:
        field: an Equinox module (the true equations of motion, or a model) called as
            ``field(state (4,), t, force (2,))``.
        y0: initial states, shape ``(N, 4)``.
        actuation: each trajectory's forcing parameters, shape ``(N, 2, 3, 3)``
            (:func:`~fhnn.physics.actuation.actuation_force`).
        ts: output times [s], shape ``(T,)``, or each trajectory's own, ``(N, T)``.
        rtol, atol, max_steps, bound: as for :func:`adaptive_solve` (``dense=False``).
        residual: recorded forces less the sinusoids at the times ``ts``, shape ``(N, T, 2)``
            (:func:`~fhnn.physics.actuation.forcing`); ``None``: the sinusoids alone.

    Returns:
        ``(states, ok)`` of shapes ``(N, T, 4)`` and ``(N,)``.
    """

    def one(s0: Array, a: Array, r: Array | None, times: Array) -> tuple[Array, Array]:
        return adaptive_solve(
            lambda s, t: field(s, t, forcing(a, t, times if r is not None else None, r)),
            s0,
            times,
            rtol=rtol,
            atol=atol,
            dense=False,
            max_steps=max_steps,
            bound=bound,
        )

    return jax.vmap(one, in_axes=(0, 0, 0, 0 if ts.ndim == 2 else None))(y0, actuation, residual, ts)
