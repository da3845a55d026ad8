"""The one interface every model implements: a vector field ``ṡ = f(s, t, F_ext)``.

A model is an Equinox module; ``model(state, t, force)`` takes one state ``(4,)`` [m, m, m/s, m/s],
a time ``t`` [s] and the known external force ``(2,)`` [N], and returns ``ṡ`` ``(4,)``. Batching is
``jax.vmap``. Training, rollout and metrics only ever see this interface.
"""

from __future__ import annotations

import abc
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.physics.actuation import actuation_force
from fhnn.physics.integrators import rk4_step

Array = jax.Array


class AbstractVectorField(eqx.Module):
    """A learned (or known) vector field ``ṡ = f(s, t, F_ext)``."""

    @abc.abstractmethod
    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        """``ṡ`` (shape ``(4,)``) at ``state`` (``(4,)``), time ``t`` [s], force ``(2,)`` [N]."""

    def regularization(self, states: Array, ts: Array) -> dict[str, Array]:
        """Extra loss terms (unweighted), evaluated at a batch of states ``(B, 4)`` and times ``(B,)``."""
        return {}

    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        """Unweighted training loss terms on a batch of windows (SPEC §5).

        ``batch``: ``s`` ``(B, W, 4)`` consecutive observed states at times ``t`` ``(B, W)``, their
        true derivatives ``deriv`` ``(B, W, 4)``, forcing ``act`` ``(B, 2, 3, 3)`` and trajectory
        index ``traj`` ``(B,)``. ``scales``: per-component std of derivatives and of one-step
        increments. The default — for every model that is a vector field — is ``{"deriv": MSE of
        f(s_0) against the true derivative, "step": MSE of one RK4 step against s_1}`` (both
        normalised by ``scales``) plus :meth:`regularization`.
        """
        deriv_scale, step_scale = scales

        def one(s: Array, t: Array, a: Array) -> tuple[Array, Array]:
            f = lambda x, tt: self(x, tt, actuation_force(a, tt))  # noqa: E731
            return f(s[0], t[0]), rk4_step(f, s[0], t[0], t[1] - t[0])

        pred_d, pred_next = jax.vmap(one)(batch["s"], batch["t"], batch["act"])
        terms = {
            "deriv": jnp.mean(((pred_d - batch["deriv"][:, 0]) / deriv_scale) ** 2),
            "step": jnp.mean(((pred_next - batch["s"][:, 1]) / step_scale) ** 2),
        }
        terms.update(self.regularization(batch["s"][:, 0], batch["t"][:, 0]))
        return terms

    def warmup_filter(self) -> Any:
        """Which parameters train during the trainer's warm-up phase: a pytree of bools shaped like
        the model (``True``: trains from the first step), or ``None`` (default): every parameter
        trains from the start and there is no warm-up."""
        return None

    @property
    def window(self) -> int:
        """Consecutive samples per training example (2: a transition pair)."""
        return 2
