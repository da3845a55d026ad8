"""Training an :class:`~fhnn.models.planar_actuated.ActuatedPlanarFHNN` on a turning body's data
set whose forces channel holds logged controls (:mod:`fhnn.data.planar_controls`).

The loss is :mod:`fhnn.training.planar`'s one-step loss, the controls read linearly within each
interval where known forces would be; the same :class:`~fhnn.training.planar.PlanarTrainConfig`
runs Adam (cosine-decayed learning rate) on random batches, then L-BFGS on a fixed subset, and the
model kept is the one with the lowest loss on the validation split.
"""

from __future__ import annotations

import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.data.planar import PlanarDataset
from fhnn.models.planar import PlanarModelConfig
from fhnn.models.planar_actuated import ActuatedPlanarFHNN, build_actuated_fhnn
from fhnn.training.planar import PlanarTrainConfig, ProgressFn, _pairs, rate_scales, step_residuals

Array = jax.Array


@dataclasses.dataclass(frozen=True)
class ActuatedFit:
    """What :func:`fit_actuated` returns: the best ``model`` (lowest validation loss), its
    ``val_loss``, the ``history`` (phase, step, train loss, validation loss) and ``seconds``."""

    model: ActuatedPlanarFHNN
    val_loss: float
    history: list[tuple[str, int, float, float]]
    seconds: float


def fit_actuated(
    dataset: PlanarDataset,
    n_controls: int,
    model_config: PlanarModelConfig | None = None,
    config: PlanarTrainConfig | None = None,
    *,
    progress: ProgressFn | None = None,
) -> ActuatedFit:
    """Train an :class:`~fhnn.models.planar_actuated.ActuatedPlanarFHNN` on ``dataset``.

    Args:
        dataset: a turning body's data set whose first ``n_controls`` force slots hold the
            controls (train and val splits used).
        n_controls: how many controls, 1 to 3.
        model_config: the body's architecture (the actuator takes its width and depth).
        config: the training (default :class:`~fhnn.training.planar.PlanarTrainConfig`).
        progress: called as ``progress(phase, step, steps, train_loss)`` at each validation.

    Returns:
        An :class:`ActuatedFit`.

    Raises:
        ValueError: ``n_controls`` is not 1, 2 or 3.
    """
    model_config = model_config or PlanarModelConfig()
    config = config or PlanarTrainConfig()
    start = time.perf_counter()
    key = jax.random.PRNGKey(config.seed)
    model = build_actuated_fhnn(model_config, dataset, n_controls, key=key)
    train, val = dataset.splits["train"], dataset.splits["val"]
    scales = rate_scales(train)
    train_pairs, val_pairs = _pairs(train), _pairs(val)
    params, static = eqx.partition(model, eqx.is_inexact_array)
    sub = config.substeps

    def loss(p: ActuatedPlanarFHNN, pairs: tuple[Array, ...]) -> Array:
        return jnp.mean(step_residuals(eqx.combine(p, static), pairs, scales, sub) ** 2)

    val_loss = eqx.filter_jit(lambda p: loss(p, val_pairs))
    history: list[tuple[str, int, float, float]] = []
    best = (float("inf"), params)

    def record(phase: str, step: int, steps: int, value: float, p: ActuatedPlanarFHNN) -> None:
        nonlocal best
        v = float(val_loss(p))
        history.append((phase, step, value, v))
        if v < best[0]:
            best = (v, p)
        if progress is not None:
            progress(phase, step, steps, value)

    n_pairs = int(train_pairs[0].shape[0])
    every = config.validate_every
    if config.adam_steps:
        adam = optax.adam(optax.cosine_decay_schedule(config.learning_rate, config.adam_steps, alpha=0.01))
        opt_state = adam.init(params)
        batch = min(config.batch_size, n_pairs)

        @eqx.filter_jit
        def adam_step(p, s, k):
            chosen = jax.random.choice(k, n_pairs, (batch,), replace=False)
            value, grads = jax.value_and_grad(loss)(p, tuple(a[chosen] for a in train_pairs))
            updates, s = adam.update(grads, s, p)
            return eqx.apply_updates(p, updates), s, value

        keys = jax.random.split(jax.random.PRNGKey(config.seed + 1), config.adam_steps)
        for i, k in enumerate(keys, start=1):
            params, opt_state, value = adam_step(params, opt_state, k)
            if i % every == 0 or i == config.adam_steps:
                record("adam", i, config.adam_steps, float(value), params)
    if config.lbfgs_steps:
        params = best[1]
        subset = np.sort(np.random.default_rng(config.seed).permutation(n_pairs)[: config.lbfgs_pairs])
        fixed = tuple(a[jnp.asarray(subset)] for a in train_pairs)

        def fixed_loss(p):
            return loss(p, fixed)

        lbfgs = optax.lbfgs(memory_size=20)
        opt_state = lbfgs.init(params)
        value_and_grad = optax.value_and_grad_from_state(fixed_loss)

        @eqx.filter_jit
        def lbfgs_step(p, s):
            value, grads = value_and_grad(p, state=s)
            updates, s = lbfgs.update(grads, s, p, value=value, grad=grads, value_fn=fixed_loss)
            return eqx.apply_updates(p, updates), s, value

        for i in range(1, config.lbfgs_steps + 1):
            params, opt_state, value = lbfgs_step(params, opt_state)
            if not np.isfinite(float(value)):
                break
            if i % every == 0 or i == config.lbfgs_steps:
                record("lbfgs", i, config.lbfgs_steps, float(value), params)
    return ActuatedFit(eqx.combine(best[1], static), best[0], history, time.perf_counter() - start)


__all__ = ["ActuatedFit", "fit_actuated"]
