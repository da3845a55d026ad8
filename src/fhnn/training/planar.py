"""Training a :class:`~fhnn.models.planar.PlanarFHNN` on a turning body's data set.

The loss is the one-step prediction error: from every state ``s_k`` of the training split,
``substeps`` RK4 steps of the model under the known forcing (``body_force`` of
:mod:`fhnn.physics.planar` on the interval) predict ``s_{k+1}``; the residual
``(ŝ_{k+1} − s_{k+1}) / (Δt · c)``, with ``c`` each state entry's RMS rate over the split, is a
scaled error of the vector field. Adam (cosine-decayed learning rate) runs
first, then L-BFGS polishes; the model kept is the one with the lowest loss on the validation split.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.planar import PlanarDataset, PlanarSplit
from fhnn.models.planar import PlanarFHNN, PlanarModelConfig, build_planar_fhnn, planar_arguments
from fhnn.physics.integrators import rk4_step
from fhnn.physics.planar import body_force

Array = jax.Array
#: Called as ``progress(phase, step, steps, train_loss)`` now and then.
ProgressFn = Callable[[str, int, int, float], None]


@frozen_config
class PlanarTrainConfig(Config):
    """How a :class:`~fhnn.models.planar.PlanarFHNN` is trained.

    Attributes:
        adam_steps: Adam steps, each on ``batch_size`` one-step pairs drawn afresh.
        batch_size: pairs per Adam step.
        learning_rate: Adam's first learning rate, decayed to 1 % of it along a cosine.
        lbfgs_steps: L-BFGS iterations after Adam (zoom line search, memory 20), on a fixed,
            seeded subset of ``lbfgs_pairs`` pairs (all of them when fewer).
        substeps: RK4 steps per sample interval in the loss.
        validate_every: steps between validation losses (the best model is kept).
        seed: the weights' seed.
    """

    config_name = "planar training"

    adam_steps: int = 4000
    batch_size: int = 256
    learning_rate: float = 3e-3
    lbfgs_steps: int = 1000
    lbfgs_pairs: int = 4000
    substeps: int = 1
    validate_every: int = 50
    seed: int = 0

    def validate(self) -> None:
        check_nonnegative(self, "adam_steps", "lbfgs_steps", "seed")
        check_positive(self, "learning_rate", "substeps", "validate_every", "batch_size", "lbfgs_pairs")


@dataclasses.dataclass(frozen=True)
class PlanarFit:
    """What :func:`fit_planar` returns: the best ``model`` (lowest validation loss), its
    ``val_loss``, the ``history`` (phase, step, train loss, validation loss) and ``seconds``."""

    model: PlanarFHNN
    val_loss: float
    history: list[tuple[str, int, float, float]]
    seconds: float


def _pairs(split: PlanarSplit) -> tuple[Array, ...]:
    """``(s_k, s_{k+1}, (t_k, t_{k+1}), thrust, (r_k, r_{k+1}))`` over every trajectory's own
    intervals (padding left out), flattened; ``r`` the forces less the sinusoids."""
    n, t = split.states.shape[:2]
    own = (split.valid()[:, 1:]).reshape(-1)
    residual = split.residual()

    def ends(a: np.ndarray) -> np.ndarray:
        return np.stack([a[:, :-1], a[:, 1:]], axis=2).reshape(n * (t - 1), 2, *a.shape[2:])[own]

    s0 = split.states[:, :-1].reshape(-1, 6)[own]
    s1 = split.states[:, 1:].reshape(-1, 6)[own]
    thrust = np.repeat(split.thrust, t - 1, axis=0)[own]
    return tuple(jnp.asarray(a) for a in (s0, s1, ends(split.t), thrust, ends(residual)))


def rate_scales(split: PlanarSplit) -> Array:
    """Each state entry's RMS rate of change over ``split``'s own intervals (finite differences),
    shape ``(6,)``."""
    rates = np.diff(split.states, axis=1) / np.diff(split.t, axis=1)[..., None]
    own = split.valid()[:, 1:]
    return jnp.asarray(np.sqrt(np.mean(rates[own] ** 2, axis=0)))


def step_residuals(model: PlanarFHNN, pairs: tuple[Array, ...], scales: Array, substeps: int) -> Array:
    """The scaled one-step residuals, shape ``(P, 6)``."""
    s0, s1, times, thrust, residual = pairs

    def one(s: Array, target: Array, ends: Array, a: Array, r: Array) -> Array:
        t, h = ends[0], ends[1] - ends[0]

        def field(state: Array, time: Array) -> Array:
            return model(state, time, body_force(a, time, ends, r))

        step = h / substeps
        for i in range(substeps):
            s = rk4_step(field, s, t + i * step, step)
        return (s - target) / (h * scales)

    return jax.vmap(one)(s0, s1, times, thrust, residual)


def _loss(
    params: PlanarFHNN, static: PlanarFHNN, pairs: tuple[Array, ...], scales: Array, substeps: int
) -> Array:
    model = eqx.combine(params, static)
    return jnp.mean(step_residuals(model, pairs, scales, substeps) ** 2)


def fit_planar(
    dataset: PlanarDataset,
    model_config: PlanarModelConfig | None = None,
    config: PlanarTrainConfig | None = None,
    *,
    progress: ProgressFn | None = None,
) -> PlanarFit:
    """Train a :class:`~fhnn.models.planar.PlanarFHNN` on ``dataset``'s train split.

    Args:
        dataset: a turning body's data set (train and val splits used).
        model_config: the architecture (default :class:`PlanarModelConfig`).
        config: the training (default :class:`PlanarTrainConfig`).
        progress: called as ``progress(phase, step, steps, train_loss)`` at each validation.

    Returns:
        A :class:`PlanarFit`.
    """
    model_config = model_config or PlanarModelConfig()
    config = config or PlanarTrainConfig()
    start = time.perf_counter()
    model = build_planar_fhnn(model_config, **planar_arguments(dataset), key=jax.random.PRNGKey(config.seed))
    train, val = dataset.splits["train"], dataset.splits["val"]
    scales = rate_scales(train)
    train_pairs, val_pairs = _pairs(train), _pairs(val)
    params, static = eqx.partition(model, eqx.is_inexact_array)
    sub = config.substeps

    val_loss = eqx.filter_jit(lambda p: _loss(p, static, val_pairs, scales, sub))

    history: list[tuple[str, int, float, float]] = []
    best = (float("inf"), params)

    def check(phase: str, step: int, steps: int, train_value: float, p: PlanarFHNN) -> None:
        nonlocal best
        v = float(val_loss(p))
        history.append((phase, step, train_value, v))
        if v < best[0]:
            best = (v, p)
        if progress is not None:
            progress(phase, step, steps, train_value)

    if config.adam_steps:
        schedule = optax.cosine_decay_schedule(config.learning_rate, config.adam_steps, alpha=0.01)
        adam = optax.adam(schedule)
        state = adam.init(params)

        n_pairs = train_pairs[0].shape[0]
        batch = min(config.batch_size, n_pairs)

        @eqx.filter_jit
        def adam_step(p, s, key):
            pick = jax.random.choice(key, n_pairs, (batch,), replace=False)
            chosen = tuple(a[pick] for a in train_pairs)
            value, grads = jax.value_and_grad(_loss)(p, static, chosen, scales, sub)
            updates, s = adam.update(grads, s, p)
            return eqx.apply_updates(p, updates), s, value

        keys = jax.random.split(jax.random.PRNGKey(config.seed + 1), config.adam_steps)
        for i in range(config.adam_steps):
            params, state, value = adam_step(params, state, keys[i])
            if (i + 1) % config.validate_every == 0 or i + 1 == config.adam_steps:
                check("adam", i + 1, config.adam_steps, float(value), params)
    if config.lbfgs_steps:
        params = best[1]
        lbfgs = optax.lbfgs(memory_size=20)
        state = lbfgs.init(params)
        n_pairs = train_pairs[0].shape[0]
        subset = np.random.default_rng(config.seed).permutation(n_pairs)[: config.lbfgs_pairs]
        fixed = tuple(a[jnp.asarray(np.sort(subset))] for a in train_pairs)

        def loss_only(p):
            return _loss(p, static, fixed, scales, sub)

        grad_from_state = optax.value_and_grad_from_state(loss_only)

        @eqx.filter_jit
        def lbfgs_step(p, s):
            value, grads = grad_from_state(p, state=s)
            updates, s = lbfgs.update(grads, s, p, value=value, grad=grads, value_fn=loss_only)
            return eqx.apply_updates(p, updates), s, value

        for i in range(config.lbfgs_steps):
            params, state, value = lbfgs_step(params, state)
            if not np.isfinite(float(value)):
                break
            if (i + 1) % config.validate_every == 0 or i + 1 == config.lbfgs_steps:
                check("lbfgs", i + 1, config.lbfgs_steps, float(value), params)
    return PlanarFit(eqx.combine(best[1], static), best[0], history, time.perf_counter() - start)


__all__ = ["PlanarFit", "PlanarTrainConfig", "fit_planar", "rate_scales", "step_residuals"]
