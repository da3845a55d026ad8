"""Baselines behind the same vector-field interface (docs/spec.md §4.2).

- :class:`NeuralODE` (Chen et al. 2018): an MLP ``(s, F_ext) → ṡ``, all four components.
- :class:`HNN` (Greydanus et al. 2019): ``H_θ(q, p)``, ``q = (x, y)``, ``p = M_θ ⊙ v`` with a
  learned positive diagonal inertia ``M_θ`` [kg] started at the body's known dry mass ``M``;
  ``q̇ = ∂H/∂p``, ``ṗ = −∂H/∂q + F_ext``. (With ``p = v``, as the specification once wrote, a force in N is
  added to an acceleration: a response ``M + m_a`` = 22–30 times too strong for the scenarios'
  bodies.) ``M_θ`` trains towards the effective mass ``M + m_a``.
- :class:`LNN` (Cranmer et al. 2020): ``L_θ(q, q̇)``;
  ``q̈ = (∇q̇∇q̇ᵀL)⁻¹ [∇q L − (∇q∇q̇ᵀL) q̇ + F_ext]`` — a linear solve, no explicit inverse and no
  conditioning fix: its ill-conditioning is part of what the comparison shows. It is trained on
  the derivative loss only, as in the original: through the four stages of an RK4 step the
  ``q̇``-Hessian of a fresh network passes through singular matrices and the step loss is NaN.
- :class:`DissipativeHNN` (after Sosanya & Greydanus 2022): ``H_θ`` plus a learned Rayleigh
  dissipation function ``D = ½ pᵀ R_θ(q) p`` with ``R_θ ⪰ 0``; ``ṗ = −∂H/∂q − ∂D/∂p + F_ext``
  with the HNN's ``p = M_θ ⊙ v``.

Inputs are standardised with the training data's statistics (stored with the model), so every
network sees O(1) inputs; the scalar functions ``H``, ``L``, ``D`` are otherwise unconstrained.
``H`` and ``L`` are in joules (their scale includes the known dry mass ``M``), so a fresh HNN or
LNN responds to a force as a body of mass ``M`` would; the LNN's ``q̇``-Hessian (its mass matrix)
then trains freely.
"""

from __future__ import annotations

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_positive, frozen_config
from fhnn.data.dataset import Dataset
from fhnn.data.windows import LossScales, Windows
from fhnn.models.base import AbstractVectorField

Array = jax.Array


@frozen_config
class MLPConfig(Config):
    """Size of a baseline's network: ``depth`` hidden layers of ``width`` units."""

    config_name = "baseline"

    width: int = 64
    depth: int = 3
    activation: Literal["tanh", "softplus"] = "tanh"

    def validate(self) -> None:
        check_positive(self, "width", "depth")


def _mlp(config: MLPConfig, n_in: int, n_out: int, key: Array) -> eqx.nn.MLP:
    act = jnp.tanh if config.activation == "tanh" else jax.nn.softplus
    return eqx.nn.MLP(n_in, n_out, config.width, config.depth, activation=act, key=key)


class Standardiser(eqx.Module):
    """``(s − mean) / std`` for states ``(4,)``; forces divided by ``force_std``."""

    mean: tuple[float, ...] = eqx.field(static=True)
    std: tuple[float, ...] = eqx.field(static=True)
    force_std: float = eqx.field(static=True)

    def state(self, s: Array) -> Array:
        return (s - jnp.asarray(self.mean)) / jnp.asarray(self.std)

    def force(self, f: Array) -> Array:
        return f / self.force_std


class NeuralODE(AbstractVectorField):
    """Black-box ``ṡ = deriv_std · MLP(standardised s, F_ext)``."""

    mlp: eqx.nn.MLP
    norm: Standardiser
    deriv_std: tuple[float, ...] = eqx.field(static=True)

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        inp = jnp.concatenate([self.norm.state(state), self.norm.force(force)])
        return jnp.asarray(self.deriv_std) * self.mlp(inp)


class HNN(AbstractVectorField):
    """``q̇ = ∂H/∂p``, ``ṗ = −∂H/∂q + F_ext`` with ``p = M_θ ⊙ v``, the inertia
    ``M_θ = mass · exp(log_inertia)`` [kg] ``(2,)`` learned, and ``H = energy_scale · MLP(ξ)`` [J],
    ``ξ`` the standardised ``(q, p / mass)`` (a fixed scaling, so the inputs stay O(1))."""

    mlp: eqx.nn.MLP
    norm: Standardiser
    log_inertia: Array
    energy_scale: float = eqx.field(static=True)
    mass: float = eqx.field(static=True)

    def inertia(self) -> Array:
        """``M_θ`` [kg], shape ``(2,)``: the learned effective mass on each axis."""
        return self.mass * jnp.exp(self.log_inertia)

    def hamiltonian(self, q: Array, p: Array) -> Array:
        """``H(q, p)`` [J] at positions ``q`` [m] and momenta ``p`` [kg·m/s], ``(2,)`` each."""
        xi = self.norm.state(jnp.concatenate([q, p / self.mass]))
        return self.energy_scale * self.mlp(xi)[0]

    def momentum_rates(self, state: Array) -> tuple[Array, Array, Array]:
        """``(q̇, −∂H/∂q, p)`` at a state ``(q, v)``."""
        p = self.inertia() * state[2:]
        dq, dp = jax.grad(self.hamiltonian, argnums=(0, 1))(state[:2], p)
        return dp, -dq, p

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        qdot, pdot, _ = self.momentum_rates(state)
        return jnp.concatenate([qdot, (pdot + force) / self.inertia()])


class DissipativeHNN(AbstractVectorField):
    """HNN plus a Rayleigh dissipation function ``D = ½ pᵀ R(q) p``, ``R = A Aᵀ ⪰ 0``:
    ``ṗ = −∂H/∂q − R(q) p + G ⊙ F_ext``. ``A(q)`` is lower-triangular, from an MLP of ``q``."""

    hnn: HNN
    dissipation: eqx.nn.MLP
    rate_scale: float = eqx.field(static=True)

    def rayleigh_matrix(self, q: Array) -> Array:
        """``R(q)`` [1/s], shape ``(2, 2)``, positive semi-definite."""
        xi = self.hnn.norm.state(jnp.concatenate([q, jnp.zeros(2)]))[:2]
        a = self.dissipation(xi)
        A = jnp.asarray([[a[0], 0.0], [a[1], a[2]]])
        return self.rate_scale * A @ A.T

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        qdot, pdot, p = self.hnn.momentum_rates(state)
        damping = self.rayleigh_matrix(state[:2]) @ p
        return jnp.concatenate([qdot, (pdot - damping + force) / self.hnn.inertia()])


class LNN(AbstractVectorField):
    """Euler–Lagrange accelerations of ``L = energy_scale · (½‖ξ_q̇‖² + MLP(ξ))``, ``ξ`` the
    standardised ``(q, q̇)``."""

    mlp: eqx.nn.MLP
    norm: Standardiser
    energy_scale: float = eqx.field(static=True)

    def lagrangian(self, q: Array, qd: Array) -> Array:
        xi = self.norm.state(jnp.concatenate([q, qd]))
        # a free particle plus the network: a skip connection that makes the q̇-Hessian of a fresh
        # model well conditioned (a plain random MLP's is near-singular and indefinite); L stays a
        # general function, and nothing limits the conditioning once training moves it
        return self.energy_scale * (0.5 * jnp.sum(xi[2:] ** 2) + self.mlp(xi)[0])

    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        """Derivative loss only (see the module doc)."""
        terms = super().loss_terms(batch, scales)
        return {"deriv": terms["deriv"]}

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        q, qd = state[:2], state[2:]
        hess_qd = jax.hessian(self.lagrangian, argnums=1)(q, qd)
        grad_q = jax.grad(self.lagrangian, argnums=0)(q, qd)
        mixed = jax.jacfwd(jax.grad(self.lagrangian, argnums=1), argnums=0)(q, qd)  # ∂²L/∂q̇∂q
        qdd = jnp.linalg.solve(hess_qd, grad_q - mixed @ qd + force)
        return jnp.concatenate([qd, qdd])


def data_statistics(dataset: Dataset) -> dict:
    """The training split's statistics a baseline standardises with: ``n_traj``; per component
    ``state_mean``, ``state_std``, ``deriv_std`` and ``step_std`` (one-step increments, the
    trainer's step scale); ``force_std`` [N] (at least 1e-3), ``energy`` (mean squared velocity
    std, the scale of ``H`` and ``L``) and the body's known dry ``mass`` [kg]."""
    train = dataset.train
    states = train.states[train.mask]  # (samples, 4): real samples only
    std = states.std(axis=0)
    return {
        "n_traj": train.n_traj,
        "step_std": LossScales.of(Windows.of(train)).step.tolist(),
        "state_mean": states.mean(axis=0).tolist(),
        "state_std": std.tolist(),
        "force_std": float(max(train.forces[train.mask].std(), 1e-3)),
        "deriv_std": train.derivs[train.mask].std(axis=0).tolist(),
        "energy": float(np.mean(std[2:] ** 2)),
        "mass": float(dataset.body_params["M"]),
    }


def build_baseline(kind: str, config: MLPConfig, stats: dict, key: Array) -> AbstractVectorField:
    """A fresh baseline ``kind`` (node, hnn, lnn, dhnn) for data with statistics ``stats``.

    ``stats``: ``state_mean``, ``state_std`` (4 each), ``force_std``, ``deriv_std`` (4), ``energy``
    and ``mass`` [kg] (the HNN's initial inertia; ``H`` and ``L`` scale as ``mass · energy``; 1 kg
    where absent).
    """
    mass = float(stats.get("mass", 1.0))
    norm = Standardiser(
        mean=tuple(stats["state_mean"]), std=tuple(stats["state_std"]), force_std=stats["force_std"]
    )
    k1, k2 = jax.random.split(key)
    if kind == "node":
        return NeuralODE(mlp=_mlp(config, 6, 4, k1), norm=norm, deriv_std=tuple(stats["deriv_std"]))
    if kind in ("hnn", "dhnn"):
        hnn = HNN(
            mlp=_mlp(config, 4, 1, k1),
            norm=norm,
            log_inertia=jnp.zeros(2),
            energy_scale=mass * stats["energy"],
            mass=mass,
        )
        if kind == "hnn":
            return hnn
        rate = float(np.mean(np.asarray(stats["deriv_std"][2:]) / np.asarray(stats["state_std"][2:])))
        return DissipativeHNN(hnn=hnn, dissipation=_mlp(config, 2, 3, k2), rate_scale=rate)
    if kind == "lnn":
        return LNN(mlp=_mlp(config, 4, 1, k1), norm=norm, energy_scale=mass * stats["energy"])
    raise ValueError(kind)
