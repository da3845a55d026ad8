"""The quasi-Newton (L-BFGS) iteration of the warm-up and polish phases, on one parameter vector."""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import optax
from jax.flatten_util import ravel_pytree

from fhnn.training import losses
from fhnn.training.train_config import TrainConfig

Array = jax.Array


def strong_types(tree: Any) -> Any:
    """``tree`` with every weakly typed array leaf made strong (same dtype). optax's L-BFGS
    initialises its line-search info as weak scalars and returns them strong after one update, so
    without this the quasi-Newton step compiles twice per phase."""
    return jax.tree.map(lambda x: jnp.asarray(x, dtype=x.dtype) if eqx.is_array(x) else x, tree)


def quasi_newton_objective(
    params: Any, static: Any, data: dict[str, Array], scales: tuple[Array, Array], config: TrainConfig
) -> Array:
    """The quasi-Newton phases' objective: the data loss (no regulariser) of
    ``combine(params, static)`` over the whole batch ``data``."""
    return losses.data_loss(losses.loss_terms(eqx.combine(params, static), data, scales), config)


@eqx.filter_jit
def quasi_newton_step(
    flat: Array,
    opt_state: Any,
    like: Any,
    static: Any,
    data: dict[str, Array],
    scales: tuple[Array, Array],
    config: TrainConfig,
) -> tuple[Array, Any, Array]:
    """One L-BFGS iteration (``config.lbfgs_memory`` pairs, zoom line search) on
    :func:`quasi_newton_objective`, with the parameters as one vector ``flat`` ``(P,)`` laid out
    as ``jax.flatten_util.ravel_pytree(like)`` lays out ``like`` (the parameters' pytree; only its
    structure, shapes and dtypes matter). On one vector each of the optimiser's operations (the
    two-loop recursion over the memory, the line search's updates) is one operation, not one per
    leaf of the model (30 for the FHNN)."""
    opt = optax.lbfgs(memory_size=config.lbfgs_memory)
    unravel = ravel_pytree(like)[1]

    def objective(f: Array) -> Array:
        return quasi_newton_objective(unravel(f), static, data, scales, config)

    value, grad = optax.value_and_grad_from_state(objective)(flat, state=opt_state)
    updates, opt_state = opt.update(grad, opt_state, flat, value=value, grad=grad, value_fn=objective)
    return optax.apply_updates(flat, updates), opt_state, value
