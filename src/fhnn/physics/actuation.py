"""Known external forcing (actuation) of the body.

Per trajectory and axis ``i``: ``F_ext,i(t) = Σ_{j=1..3} A_ij sin(2π f_ij t + φ_ij)``, stored as an
array of shape ``(2, 3, 3)``: ``[axis, mode, (amplitude [N], frequency [Hz], phase [rad])]``.
A trajectory without actuation has all amplitudes zero.

Models see the force a data set *records* (its ``forces`` at the sample times), through
:func:`forcing`: the sinusoids of the parameters (exact between samples) plus the linear
interpolant of what the recorded samples add to them (:func:`force_residual`). For simulated data
the recorded forces are the sinusoids, the residual is zero and the force exact; for data whose
forcing is known only as samples (all amplitudes zero, forces recorded) it is the interpolant of
the samples. Held forcing (thrusters that switch between samples) adds a change time per
sample interval: :func:`held_grid` makes the interpolant the step function for adaptive solves,
:func:`~fhnn.physics.integrators.rk4_solve_held` splits RK4 steps there.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

Array = jax.Array

N_MODES = 3


def actuation_force(params: Array, t: Array) -> Array:
    """``F_ext(t)`` [N], shape ``(2,)``, for ``params`` of shape ``(2, 3, 3)`` and scalar ``t`` [s]."""
    amp, freq, phase = params[..., 0], params[..., 1], params[..., 2]
    return jnp.sum(amp * jnp.sin(2.0 * math.pi * freq * t + phase), axis=-1)


def sample_actuation(
    rng: np.random.Generator,
    n: int,
    *,
    amplitude: float = 1.0,
    f_min: float = 0.05,
    f_max: float = 0.5,
) -> np.ndarray:
    """Draw ``n`` actuation parameter sets, shape ``(n, 2, 3, 3)``.

    ``A ~ U(0, amplitude)`` [N], ``f ~ U(f_min, f_max)`` [Hz], ``φ ~ U(0, 2π)``.
    """
    shape = (n, 2, N_MODES)
    return np.stack(
        [
            rng.uniform(0.0, amplitude, shape),
            rng.uniform(f_min, f_max, shape),
            rng.uniform(0.0, 2.0 * math.pi, shape),
        ],
        axis=-1,
    )


def no_actuation(n: int) -> np.ndarray:
    """``n`` parameter sets with zero force, shape ``(n, 2, 3, 3)``."""
    return np.zeros((n, 2, N_MODES, 3))


def force_residual(
    params: np.ndarray, t: np.ndarray, forces: np.ndarray, *, rtol: float = 1e-9
) -> np.ndarray:
    """Recorded ``forces`` ``(N, T, 2)`` [N] at times ``t`` ``(T,)`` (or each trajectory's own,
    ``(N, T)``) less the sinusoids of ``params`` ``(N, 2, 3, 3)``, with differences within rounding
    (``rtol`` of the force scale) set to exactly 0."""
    forces = np.asarray(forces, dtype=float)
    t = np.broadcast_to(np.asarray(t, dtype=float), forces.shape[:2])
    params = np.asarray(params, dtype=float)
    residual = forces.copy()
    # :func:`actuation_force` in NumPy (eager JAX compiled a program per primitive: 0.3 s per split
    # read), only for the trajectories that have sinusoids
    active = np.flatnonzero(np.any(params[..., 0] != 0.0, axis=(1, 2)))
    if active.size:
        p = params[active][:, None]  # (n, 1, 2, 3, 3)
        arg = 2.0 * math.pi * p[..., 1] * t[active][:, :, None, None] + p[..., 2]
        residual[active] -= np.sum(p[..., 0] * np.sin(arg), axis=-1)
    scale = max(1.0, float(np.max(np.abs(forces), initial=0.0)))
    residual[np.abs(residual) <= rtol * scale] = 0.0
    return residual


def forcing(params: Array, t: Array, knots: Array | None = None, residual: Array | None = None) -> Array:
    """``F_ext(t)`` [N], shape ``(2,)``: the sinusoids of ``params`` ``(2, 3, 3)`` plus, when given,
    the linear interpolant at ``t`` of ``residual`` ``(K, 2)`` sampled at the increasing times
    ``knots`` ``(K,)`` (held constant outside them)."""
    force = actuation_force(params, t)
    if residual is None or knots is None:
        return force
    return force + jnp.stack([jnp.interp(t, knots, residual[:, 0]), jnp.interp(t, knots, residual[:, 1])])


#: The width [s] of the ramp that stands for a step of a held force in a linear interpolant.
STEP_WIDTH = 1e-6
#: Padding after a row's last time in :func:`held_grid`: times go on in steps of this [s].
GRID_PAD = 1e-6


def held_grid(
    t: np.ndarray, residual: np.ndarray, switch: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knots whose linear interpolant is a held (step-wise) force, for solvers that step onto
    every knot.

    Args:
        t: sample times [s], shape ``(N, T)``, increasing along each row.
        residual: the force in effect at each sample [N], shape ``(N, T, 2)``.
        switch: when, in each interval ``k``, the force changes from ``residual[:, k]`` to
            ``residual[:, k + 1]`` [s], shape ``(N, T)`` (``t[:, k + 1]``: at the next sample;
            the last entry unused).

    Returns:
        ``(grid (N, L), values (N, L, 2), picks (N, T))``: the sample times with, for each
        interval whose force changes, a knot :data:`STEP_WIDTH` s before the change (the force
        before) and, for a change strictly inside the interval, one at it (the force after);
        rows padded to one length past their end (force held); ``grid[i, picks[i]] == t[i]``.
    """
    rows = []
    for i in range(t.shape[0]):
        lo, hi, at = t[i, :-1], t[i, 1:], np.clip(switch[i, :-1], t[i, :-1], t[i, 1:])
        k = np.flatnonzero(np.any(residual[i, 1:] != residual[i, :-1], axis=1))
        # before the change (a change at the interval's start: just after it, the force after)
        start = at[k] <= lo[k]
        before = at[k] - np.minimum(STEP_WIDTH, 0.5 * (at[k] - lo[k]))
        after_start = lo[k] + np.minimum(STEP_WIDTH, 0.5 * (hi[k] - lo[k]))
        times = [t[i], np.where(start, after_start, before)]
        values = [residual[i], np.where(start[:, None], residual[i, k + 1], residual[i, k])]
        inside = (at[k] > lo[k]) & (at[k] < hi[k])
        times.append(at[k][inside])
        values.append(residual[i, k[inside] + 1])
        times, values = np.concatenate(times), np.concatenate(values)
        order = np.argsort(times, kind="stable")
        rows.append((times[order], values[order]))
    size = max(times.size for times, _ in rows)
    grid = np.empty((t.shape[0], size))
    values = np.empty((t.shape[0], size, 2))
    for i, (times, vals) in enumerate(rows):
        extra = size - times.size
        grid[i] = np.concatenate([times, times[-1] + GRID_PAD * np.arange(1, extra + 1)])
        values[i] = np.concatenate([vals, np.repeat(vals[-1:], extra, axis=0)])
    picks = np.stack([np.searchsorted(grid[i], t[i]) for i in range(t.shape[0])])
    return grid, values, picks
