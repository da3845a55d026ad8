"""A turning body's model fitted to the observed poses themselves: windowed whole-track fit.

The one-step loss of :mod:`fhnn.training.planar` runs between smoothed states, so the
smoother's errors in the velocities (estimated, never observed) become the model's. This fit
compares the model with what was observed: each training trajectory is cut into windows of
``window`` seconds; from a start state of its own (free, started at the smoothed state) the model
is integrated through the window's sample times under the known forcing (RK4, ``substeps`` per
interval), and the residuals are the observed positions' and heading's misfits, each over its
estimated noise:

    r = ((x̂ − x) / σ_pos, (ŷ − y) / σ_pos, wrap(ψ̂ − ψ) / σ_ψ)   at every sample of every window.

The model's parameters and the windows' start states are fitted together by L-BFGS on the mean
square. A guard keeps the starting model when the fit does not lower the validation windows'
misfit (their rollouts from the smoothed states, nothing refitted).
"""

from __future__ import annotations

import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.config import Config, check_positive, frozen_config
from fhnn.data.planar import PlanarDataset, PlanarSplit
from fhnn.errors import ConfigError
from fhnn.models.planar import PlanarFHNN
from fhnn.physics.integrators import rk4_step
from fhnn.physics.planar import body_force

Array = jax.Array


@frozen_config
class PlanarTrackConfig(Config):
    """How :func:`fit_planar_tracks` runs.

    Attributes:
        window: each window's length [s] (its sample count is the nearest to it at the split's
            median sample step, at least 3).
        steps: L-BFGS iterations (memory 20, Armijo backtracking from a unit step).
        substeps: RK4 steps per sample interval.
    """

    config_name = "planar track fit"

    window: float = 10.0
    steps: int = 300
    substeps: int = 2

    def validate(self) -> None:
        check_positive(self, "window", "steps", "substeps")


@dataclasses.dataclass(frozen=True)
class PlanarTrackFit:
    """What :func:`fit_planar_tracks` returns: the ``model`` kept, the validation misfit
    ``val_before`` and ``val_after`` (mean squared noise-scaled pose residual of the validation
    windows), whether the fit was ``kept``, the training objective's ``history`` and
    ``seconds``."""

    model: PlanarFHNN
    val_before: float
    val_after: float
    kept: bool
    history: list[float]
    seconds: float


@dataclasses.dataclass(frozen=True)
class Windows:
    """``W`` windows of ``K`` samples: times ``t`` ``(W, K)`` [s], observed pose ``pose``
    ``(W, K, 3)``, smoothed ``start`` state ``(W, 6)``, the forces less the sinusoids ``residual``
    ``(W, K, 3)`` and the sinusoids ``thrust`` ``(W, 3, 3, 3)``."""

    t: Array
    pose: Array
    start: Array
    residual: Array
    thrust: Array


def window_size(split: PlanarSplit, window: float) -> int:
    """Samples per window: ``window`` [s] at the split's median sample step, at least 3."""
    steps = np.diff(split.t, axis=1)[split.valid()[:, 1:]]
    return max(3, round(window / float(np.median(steps))) + 1)


def observed_pose(dataset: PlanarDataset, split: PlanarSplit) -> np.ndarray:
    """What was observed of the pose, ``(N, T, 3)``: an import's table (``states_clean``), a
    simulation's noisy observations (``states``; its ``states_clean`` is the truth)."""
    return split.states[..., :3] if dataset.has_truth else split.states_clean[..., :3]


def make_windows(split: PlanarSplit, size: int, pose: np.ndarray) -> Windows:
    """Every trajectory of ``split`` cut into windows of ``size`` samples, one after another; a
    last window ends at the trajectory's last sample (overlapping the one before it). A trajectory
    shorter than ``size`` gives none. ``pose`` ``(N, T, 3)``: the observed pose
    (:func:`observed_pose`); the starts are ``split.states``.

    Raises:
        ConfigError: no trajectory holds ``size`` samples.
    """
    residual = split.residual()
    picks = []
    for k, n in enumerate(split.lengths):
        starts = list(range(0, int(n) - size + 1, size - 1))
        if starts and starts[-1] + size < n:
            starts.append(int(n) - size)
        picks += [(k, s) for s in starts]
    if not picks:
        raise ConfigError(f"no trajectory holds a window of {size} samples; shorten the window")
    rows = np.asarray([k for k, _ in picks])
    cols = np.asarray([s for _, s in picks])[:, None] + np.arange(size)[None, :]
    return Windows(
        t=jnp.asarray(split.t[rows[:, None], cols]),
        pose=jnp.asarray(pose[rows[:, None], cols]),
        start=jnp.asarray(split.states[rows, cols[:, 0]]),
        residual=jnp.asarray(residual[rows[:, None], cols]),
        thrust=jnp.asarray(split.thrust[rows]),
    )


def noise_scales(dataset: PlanarDataset) -> tuple[float, float]:
    """``(σ_pos [m], σ_ψ [rad])``: an import's estimated noise, or a simulation's ``obs_noise``
    (floored at 1e-6: noise-free data weigh a metre and a radian alike)."""
    noise = dataset.params.get("noise")
    if isinstance(noise, dict):
        pos, psi = float(noise["position"]), float(noise["heading"])
    else:
        pos = psi = float(dataset.obs_noise)
    return max(pos, 1e-6), max(psi, 1e-6)


def rollout(
    model: PlanarFHNN, start: Array, w_t: Array, thrust: Array, residual: Array, substeps: int
) -> Array:
    """The states of one window from ``start`` ``(6,)`` at its sample times ``w_t`` ``(K,)``,
    shape ``(K, 6)``."""

    def field(state: Array, time: Array) -> Array:
        return model(state, time, body_force(thrust, time, w_t, residual))

    def step(s: Array, ends: Array) -> tuple[Array, Array]:
        h = (ends[1] - ends[0]) / substeps
        for i in range(substeps):
            s = rk4_step(field, s, ends[0] + i * h, h)
        return s, s

    _, rest = jax.lax.scan(step, start, jnp.stack([w_t[:-1], w_t[1:]], axis=1))
    return jnp.concatenate([start[None], rest], axis=0)


def pose_residuals(
    model: PlanarFHNN, starts: Array, windows: Windows, scale: tuple[float, float], substeps: int
) -> Array:
    """Noise-scaled pose residuals of every window's rollout from ``starts`` ``(W, 6)``, shape
    ``(W, K, 3)``."""
    states = jax.vmap(lambda s, t, a, r: rollout(model, s, t, a, r, substeps))(
        starts, windows.t, windows.thrust, windows.residual
    )
    diff = states[..., :3] - windows.pose
    heading = jnp.arctan2(jnp.sin(diff[..., 2]), jnp.cos(diff[..., 2]))
    return jnp.concatenate([diff[..., :2] / scale[0], heading[..., None] / scale[1]], axis=-1)


def _lbfgs(objective, x, steps: int, memory: int = 20) -> tuple[object, list[float]]:
    """``steps`` L-BFGS iterations on ``objective(x)`` with an Armijo backtracking line search
    (from a unit step, halving, at most 30 times) run from Python: two compiled programs, the
    value and gradient and the value alone, where optax's zoom line search traces the objective
    inside its loop again (four times the compilation here). Returns the final ``x`` and the
    objective's values at the accepted iterates; stops early when no step lowers the
    objective."""
    value_and_grad = eqx.filter_jit(jax.value_and_grad(objective))
    value_only = eqx.filter_jit(objective)
    direction = optax.scale_by_lbfgs(memory_size=memory)
    update = eqx.filter_jit(direction.update)
    state = direction.init(x)
    history: list[float] = []
    value, grad = value_and_grad(x)
    for _ in range(steps):
        d, state = update(grad, state, x)
        leaves = zip(jax.tree_util.tree_leaves(grad), jax.tree_util.tree_leaves(d), strict=True)
        slope = float(sum(jnp.vdot(a, b) for a, b in leaves))
        current = float(value)
        if not (np.isfinite(current) and slope > 0):
            break
        alpha, accepted = 1.0, None
        for _ in range(30):
            trial = jax.tree_util.tree_map(lambda a, b, step=alpha: a - step * b, x, d)
            v = float(value_only(trial))
            if np.isfinite(v) and v <= current - 1e-4 * alpha * slope:
                accepted = trial
                break
            alpha *= 0.5
        if accepted is None:
            break
        x = accepted
        value, grad = value_and_grad(x)
        history.append(float(value))
    return x, history


def fit_planar_tracks(
    model: PlanarFHNN, dataset: PlanarDataset, config: PlanarTrackConfig | None = None
) -> PlanarTrackFit:
    """Fit ``model`` and the training windows' start states to the observed poses (module
    docstring); keep the fit only where it lowers the validation windows' misfit.

    Args:
        model: a trained model (e.g. :func:`fhnn.training.planar.fit_planar`'s).
        dataset: its data set (train and val splits used).
        config: the fit's settings (default :class:`PlanarTrackConfig`).

    Returns:
        A :class:`PlanarTrackFit`.

    Raises:
        ConfigError: a window longer than every trajectory of a split.
    """
    config = config or PlanarTrackConfig()
    begin = time.perf_counter()
    train, val = dataset.splits["train"], dataset.splits["val"]
    size = window_size(train, config.window)
    w_train = make_windows(train, size, observed_pose(dataset, train))
    w_val = make_windows(val, size, observed_pose(dataset, val))
    scale = noise_scales(dataset)
    sub = config.substeps
    params, static = eqx.partition(model, eqx.is_inexact_array)
    # the starts move in units of the noise (positions, heading) and of its rate over a step
    step = float(np.median(np.diff(np.asarray(w_train.t), axis=1)))
    unit = jnp.asarray([scale[0], scale[0], scale[1], scale[0] / step, scale[0] / step, scale[1] / step])

    def objective(p: tuple[PlanarFHNN, Array]) -> Array:
        m = eqx.combine(p[0], static)
        return jnp.mean(pose_residuals(m, w_train.start + p[1] * unit, w_train, scale, sub) ** 2)

    @eqx.filter_jit
    def val_misfit(p: PlanarFHNN) -> Array:
        return jnp.mean(pose_residuals(eqx.combine(p, static), w_val.start, w_val, scale, sub) ** 2)

    before = float(val_misfit(params))
    x = (params, jnp.zeros_like(w_train.start))
    x, history = _lbfgs(objective, x, config.steps)
    after = float(val_misfit(x[0]))
    kept = bool(np.isfinite(after) and after < before)
    chosen = x[0] if kept else params
    return PlanarTrackFit(
        eqx.combine(chosen, static), before, after, kept, history, time.perf_counter() - begin
    )


__all__ = [
    "PlanarTrackConfig",
    "PlanarTrackFit",
    "Windows",
    "fit_planar_tracks",
    "make_windows",
    "noise_scales",
    "observed_pose",
    "pose_residuals",
    "rollout",
    "window_size",
]
