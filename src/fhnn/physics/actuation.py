"""Known external forcing (actuation) of the body.

Per trajectory and axis ``i``: ``F_ext,i(t) = Σ_{j=1..3} A_ij sin(2π f_ij t + φ_ij)``, stored as an
array of shape ``(2, 3, 3)``: ``[axis, mode, (amplitude [N], frequency [Hz], phase [rad])]``.
A trajectory without actuation has all amplitudes zero.

Models see the force a data set *records* (its ``forces`` at the sample times), through
:func:`forcing`: the sinusoids of the parameters (exact between samples) plus the linear
interpolant of what the recorded samples add to them (:func:`force_residual`). For simulated data
the recorded forces are the sinusoids, the residual is zero and the force exact; for data whose
forcing is known only as samples (all amplitudes zero, forces recorded) it is the interpolant of
the samples.
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
