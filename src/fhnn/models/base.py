"""The one interface every model implements: a vector field ``ṡ = f(s, t, F_ext)``.

A model is an Equinox module; ``model(state, t, force)`` takes one state ``(4,)`` [m, m, m/s, m/s],
a time ``t`` [s] and the known external force ``(2,)`` [N], and returns ``ṡ`` ``(4,)``. Batching is
``jax.vmap``. Training, rollout and metrics only ever see this interface.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax

Array = jax.Array


class AbstractVectorField(eqx.Module):
    """A learned (or known) vector field ``ṡ = f(s, t, F_ext)``."""

    @abc.abstractmethod
    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        """``ṡ`` (shape ``(4,)``) at ``state`` (``(4,)``), time ``t`` [s], force ``(2,)`` [N]."""

    def regularization(self, states: Array, ts: Array) -> dict[str, Array]:
        """Extra loss terms (unweighted), evaluated at a batch of states ``(B, 4)`` and times ``(B,)``."""
        return {}
