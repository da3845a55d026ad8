"""The training loss: a model's loss terms, their weights, and the data loss they sum to."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.models.base import AbstractModel
from fhnn.training.train_config import TrainConfig

Array = jax.Array


#: Loss terms that are regularisers: weighted by the annealed ``lambda_flow``, left out of validation.
REGULARIZERS = ("flow",)


def loss_terms(
    model: AbstractModel, batch: dict[str, Array], scales: tuple[Array, Array]
) -> dict[str, Array]:
    """The model's unweighted loss terms on a batch (see :meth:`AbstractModel.loss_terms`)."""
    return model.loss_terms(batch, scales)


#: The data terms whose weights the configuration sets (``w_deriv``, ``w_step``, ``w_shoot``).
DATA_TERMS = ("deriv", "step", "shoot")


def term_weight(name: str, config: TrainConfig) -> float:
    """The weight of data term ``name`` in the loss: ``w_deriv``, ``w_step``, ``w_shoot``, or 1
    for a model-specific objective term."""
    return {"deriv": config.w_deriv, "step": config.w_step, "shoot": config.w_shoot}.get(name, 1.0)


def data_loss(terms: dict[str, Array], config: TrainConfig) -> Array:
    """Weighted sum of the data terms: ``w_deriv·deriv + w_step·step + w_shoot·shoot`` plus any model-specific
    objective term (weight 1); regularisers excluded. A term of weight 0 is left out, not
    multiplied by 0, so a compiled loss that only this sum reads does not compute it at all (the
    one-step RK4 term is ~2/3 of an FHNN step's cost)."""
    weighted = ((term_weight(k, config), v) for k, v in terms.items() if k not in REGULARIZERS)
    return sum((w * v for w, v in weighted if w), jnp.zeros(()))


@eqx.filter_jit
def _validation_terms(model: AbstractModel, data: dict[str, Array], scales: tuple[Array, Array]) -> dict:
    return loss_terms(model, data, scales)
