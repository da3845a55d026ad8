"""A turning body's state fitted by a model to a short stretch of observed poses.

A smoother's estimate of the velocity at a track's edge is its least certain: from positions
with 2 cm noise at 0.5 s it can be a few cm/s off, and an unstable hull turns that into metres
within a minute. A forecast therefore starts better from the state the model itself fits to the
last few seconds of observations: the start ``s₀`` at the stretch's first sample that minimises

    Σ_k ((x̂_k − x_k) / σ_pos)² + ((ŷ_k − y_k) / σ_pos)² + (wrap(ψ̂_k − ψ_k) / σ_ψ)²

over the stretch's samples, ``ŝ_k`` the model's rollout from ``s₀`` under the recorded forcing
(:func:`~fhnn.data.planar.solve_planar`, Dopri8 at the evaluation's tolerance). Each track is
fitted on its own (a block-diagonal Jacobian, by finite differences grouped over the tracks:
seven batched rollouts per Jacobian whatever their number), by SciPy's trust-region least squares
from the smoothed estimate.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import block_diag

from fhnn.data.planar import solve_planar
from fhnn.errors import ConfigError
from fhnn.evaluation.planar import ROLLOUT_BOUND, ROLLOUT_TOL


def fit_start_states(
    model,
    start: np.ndarray,
    t: np.ndarray,
    pose: np.ndarray,
    residual: np.ndarray,
    thrust: np.ndarray,
    noise: tuple[float, float],
    *,
    observed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Fit each track's state at its first sample to its observed poses.

    Args:
        model: a turning body's model or equations, called as ``model(state (6,), t, τ (3,))``.
        start: the first guess of each track's state at ``t[:, 0]``, ``(N, 6)`` [m, m, rad,
            m/s, m/s, rad/s].
        t: the samples' times [s], ``(N, K)``, increasing along each row.
        pose: the observed pose ``x, y, ψ`` [m, m, rad] at them, ``(N, K, 3)``.
        residual: the forcing at them less the sinusoids ``thrust``, ``(N, K, 3)`` (as
            :func:`~fhnn.data.planar.solve_planar` takes them); thrust: ``(N, 3, 3, 3)``.
        noise: the observations' standard deviations, position [m] and heading [rad].
        observed: which samples count, ``(N, K)`` bool (default all); a padded sample does not.

    Returns:
        ``(start, states)``: the fitted states at ``t[:, 0]``, ``(N, 6)``, and the model's rollout
        from them at every ``t``, ``(N, K, 6)``.

    Raises:
        ConfigError: a noise level that is not positive, or a track with fewer than three
            counted samples.
    """
    start, t, pose = np.asarray(start, float), np.asarray(t, float), np.asarray(pose, float)
    n, k = t.shape
    mask = np.ones((n, k), bool) if observed is None else np.asarray(observed, bool)
    if not all(np.isfinite(s) and s > 0 for s in noise):
        raise ConfigError(f"the noise levels must be positive, got {tuple(noise)}")
    if (mask.sum(axis=1) < 3).any():
        raise ConfigError("a start state is fitted to at least 3 observed samples per track")
    scale = np.array([noise[0], noise[0], noise[1]])
    weight = mask[..., None] / scale
    times, forcing, sinusoids = jnp.asarray(t), jnp.asarray(residual), jnp.asarray(thrust)

    def rollout(y0: np.ndarray) -> np.ndarray:
        states, _ = solve_planar(
            model, jnp.asarray(y0), sinusoids, times, forcing, tol=ROLLOUT_TOL, bound=ROLLOUT_BOUND
        )
        return np.asarray(states)

    def misfit(flat: np.ndarray) -> np.ndarray:
        err = rollout(flat.reshape(n, 6))[..., :3] - pose
        err[..., 2] = np.angle(np.exp(1j * err[..., 2]))
        out = err * weight
        return np.where(np.isfinite(out), out, 1e6).ravel()

    # residual block i (3K rows) depends on start i (6 columns) alone
    sparsity = block_diag([np.ones((3 * k, 6))] * n, format="csr")
    fit = least_squares(misfit, start.ravel(), jac_sparsity=sparsity, x_scale="jac", method="trf")
    fitted = fit.x.reshape(n, 6)
    return fitted, rollout(fitted)


__all__ = ["fit_start_states"]
