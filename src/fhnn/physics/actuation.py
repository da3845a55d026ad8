"""Known external forcing (actuation) of the body.

Per trajectory and axis ``i``: ``F_ext,i(t) = Σ_{j=1..3} A_ij sin(2π f_ij t + φ_ij)``, stored as an
array of shape ``(2, 3, 3)``: ``[axis, mode, (amplitude [N], frequency [Hz], phase [rad])]``.
A trajectory without actuation has all amplitudes zero.
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
