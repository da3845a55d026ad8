"""Equations of motion of a planar rigid body that turns, in a 2-D flow (docs/spec.md §7).

State ``s = (x, y, ψ, u, v, r)``: pose in the world frame [m, m, rad, ψ counter-clockwise from the
x-axis] and body-frame velocity [m/s forward, m/s to port, rad/s]. With ``R(ψ)`` the planar rotation,
``S = [[0, −1], [1, 0]]``, the water at the body ``ν_c = (R(ψ)ᵀ u_flow(x, y, t), ω/2)`` (``ω`` the
flow's vorticity) and ``ν_r = ν − ν_c``:

    ``(M_RB + M_A) ν̇ = τ − C_RB(ν) ν − C_A(ν_r, r) ν_r − M_A (r S ν_c,xy, 0) − D(ν_r) ν_r``
    ``(ẋ, ẏ) = R(ψ)(u, v)``,  ``ψ̇ = r``

Both Coriolis–centripetal terms are the turning of a momentum ``p`` by the frame's rate ``r``
together with the moment of the translational velocity on it, ``C ν = (−r p_y, r p_x, u p_y − v p_x)``
(Kirchhoff's equations in the plane): ``p = M_RB ν`` for the body, ``p = M_A ν_r`` with ``(u_r, v_r)``
for the added mass, whose third entry is the Munk moment. ``τ = (X, Y, N)`` are known body-frame
forces [N] and moment [N·m] at the tracked point (the body-frame origin).
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.physics.actuation import actuation_force
from fhnn.physics.body import AbstractLaw
from fhnn.physics.flows import AbstractFlow
from fhnn.physics.numerics import safe_norm

Array = jax.Array

SIGMA_EPS = 1e-6
#: Names of the state's six entries, in order.
STATE_NAMES = ("x", "y", "psi", "u", "v", "r")


def rotation(psi: Array) -> Array:
    """``R(ψ)``, shape ``(2, 2)``: body-frame vectors to world-frame ones."""
    c, s = jnp.cos(psi), jnp.sin(psi)
    return jnp.array([[c, -s], [s, c]])


def rigid_body_mass(mass: Array, inertia: Array, x_g: Array) -> Array:
    """``M_RB = [[m, 0, 0], [0, m, m x_G], [0, m x_G, I_z]]``, shape ``(3, 3)``.

    Args:
        mass: ``m`` [kg].
        inertia: ``I_z`` [kg·m²] about the tracked point.
        x_g: the centre of gravity ahead of the tracked point [m].
    """
    z = jnp.zeros_like(jnp.asarray(mass, float))
    return jnp.array([[mass, z, z], [z, mass, mass * x_g], [z, mass * x_g, inertia]])


def added_mass_matrix(diagonal: Array, m_26: Array = 0.0) -> Array:
    """``M_A = [[m_11, 0, 0], [0, m_22, m_26], [0, m_26, m_66]]``, shape ``(3, 3)``, from
    ``diagonal = (m_11, m_22, m_66)`` [kg, kg, kg·m²] and ``m_26`` [kg·m]."""
    m11, m22, m66 = diagonal[0], diagonal[1], diagonal[2]
    z = jnp.zeros_like(m11)
    return jnp.array([[m11, z, z], [z, m22, m_26], [z, m_26, m66]])


def body_force(thrust: Array, t: Array, knots: Array, residual: Array) -> Array:
    """``τ(t) = (X, Y, N)`` [N, N, N·m], shape ``(3,)``: the thrusters' sinusoids ``thrust``
    ``(3, 3, 3)`` (:func:`~fhnn.physics.actuation.actuation_force`) plus the linear interpolant at
    ``t`` [s] of ``residual`` ``(K, 3)`` sampled at the increasing times ``knots`` ``(K,)`` (held
    constant outside them)."""
    return actuation_force(thrust, t) + jax.vmap(jnp.interp, (None, None, 1))(t, knots, residual)


def coriolis(momentum: Array, velocity: Array, rate: Array) -> Array:
    """``C ν = (−r p_y, r p_x, u p_y − v p_x)``, shape ``(3,)``: a momentum ``p = momentum`` (its
    first two entries used) turned by the frame's ``rate`` [rad/s] and the moment of the
    translational ``velocity = (u, v, …)`` on it."""
    px, py = momentum[0], momentum[1]
    u, v = velocity[0], velocity[1]
    return jnp.stack([-rate * py, rate * px, u * py - v * px])


class AbstractPlanarDamping(eqx.Module):
    """The hydrodynamic damping ``D(ν_r) ν_r`` [N, N, N·m] of a relative velocity ``ν_r``,
    dissipative: ``ν_rᵀ D(ν_r) ν_r ≥ 0``."""

    @abc.abstractmethod
    def __call__(self, nu_r: Array) -> Array:
        """``D(ν_r) ν_r`` for ``ν_r`` of shape ``(3,)``; shape ``(3,)``."""


class DiagonalDamping(AbstractPlanarDamping):
    """The simulator's damping (docs/spec.md §7): per axis a linear and a quadratic term, the
    translational ones with the 2-DOF law's dependence on ``σ = ‖(u_r, v_r)‖ + ε``:
    ``X_d = (c_l,u + ½ ρ A_u c_q(σ) σ) u_r``, ``Y_d = (c_l,v + ½ ρ A_v c_q(σ) σ) v_r``,
    ``N_d = (c_l,r + c_q,r |r_r|) r_r``.

    Attributes:
        linear: ``(c_l,u, c_l,v, c_l,r)`` [N·s/m, N·s/m, N·m·s].
        areas: ``(A_u, A_v)`` [m²].
        quadratic: ``c_q(σ)`` [-], a law of ``σ`` (its radius argument unused).
        yaw_quadratic: ``c_q,r`` [N·m·s²].
        rho: water density [kg/m³].
        eps: ``ε`` [m/s].
    """

    linear: tuple[float, float, float]
    areas: tuple[float, float]
    quadratic: AbstractLaw
    yaw_quadratic: float
    rho: float = 1000.0
    eps: float = SIGMA_EPS

    def coefficients(self, nu_r: Array) -> Array:
        """The diagonal of ``D(ν_r)``, shape ``(3,)``, all ``≥ 0`` for nonnegative constants."""
        sigma = safe_norm(nu_r[:2]) + self.eps
        c_q = self.quadratic(jnp.zeros(()), sigma)
        lin = jnp.asarray(self.linear, float)
        area = jnp.asarray(self.areas, float)
        trans = lin[:2] + 0.5 * self.rho * area * c_q * sigma
        yaw = lin[2] + self.yaw_quadratic * jnp.abs(nu_r[2])
        return jnp.concatenate([trans, yaw[None]])

    def __call__(self, nu_r: Array) -> Array:
        return self.coefficients(nu_r) * nu_r


def water_at_body(flow: AbstractFlow, pose: Array, t: Array) -> Array:
    """``ν_c = (R(ψ)ᵀ u_flow(x, y, t), ω/2)``, shape ``(3,)``: the water's velocity in the body
    frame [m/s] and its local rotation rate, half the vorticity ``ω = ∂u_y/∂x − ∂u_x/∂y`` [rad/s],
    at ``pose = (x, y, ψ)``."""
    xy = pose[:2]
    u = flow.velocity(xy, t)
    grad = flow.velocity_gradient(xy, t)
    omega = grad[1, 0] - grad[0, 1]
    return jnp.concatenate([rotation(pose[2]).T @ u, (0.5 * omega)[None]])


class PlanarEquations(eqx.Module):
    """``ṡ = f(s, t, τ)`` of a planar body that turns (docs/spec.md §7).

    Attributes:
        flow: the background flow.
        damping: ``ν_r ↦ D(ν_r) ν_r``.
        mass: ``m`` [kg].
        inertia: ``I_z`` [kg·m²] about the tracked point.
        added_mass: ``(m_11, m_22, m_66)`` [kg, kg, kg·m²], shape ``(3,)``.
        x_g: the centre of gravity ahead of the tracked point [m].
        m_26: the sway–yaw added-mass coupling [kg·m].
    """

    flow: AbstractFlow
    damping: AbstractPlanarDamping
    mass: float | Array
    inertia: float | Array
    added_mass: Array
    x_g: float | Array = 0.0
    m_26: float | Array = 0.0

    def mass_matrix(self) -> Array:
        """``M_RB + M_A``, shape ``(3, 3)``."""
        return rigid_body_mass(self.mass, self.inertia, self.x_g) + added_mass_matrix(
            jnp.asarray(self.added_mass), self.m_26
        )

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        """``ṡ``, shape ``(6,)``, for one state ``(6,)`` at time ``t`` [s] under the known
        body-frame forces and moment ``τ = force`` [N, N, N·m], shape ``(3,)``."""
        pose, nu = state[:3], state[3:]
        nu_c = water_at_body(self.flow, pose, t)
        nu_r = nu - nu_c
        m_a = added_mass_matrix(jnp.asarray(self.added_mass), self.m_26)
        m_rb = rigid_body_mass(self.mass, self.inertia, self.x_g)
        r = nu[2]
        frame = r * jnp.array([-nu_c[1], nu_c[0], 0.0])  # (r S ν_c,xy, 0)
        rhs = (
            force
            - coriolis(m_rb @ nu, nu, r)
            - coriolis(m_a @ nu_r, nu_r, r)
            - m_a @ frame
            - self.damping(nu_r)
        )
        nu_dot = jnp.linalg.solve(m_rb + m_a, rhs)
        xy_dot = rotation(pose[2]) @ nu[:2]
        return jnp.concatenate([xy_dot, r[None], nu_dot])

    def kinetic_energy(self, state: Array) -> Array:
        """``T = ½ νᵀ (M_RB + M_A) ν`` [J] of one state ``(6,)``."""
        nu = state[3:]
        return 0.5 * nu @ self.mass_matrix() @ nu


def munk_growth_rate(
    mass: float, inertia: float, added_mass: tuple[float, float, float], speed: float
) -> float:
    """The linearised growth rate λ [1/s] of sway and yaw of an elongated body (``m_22 > m_11``,
    ``x_G = 0``, no damping) moving straight ahead at ``speed`` [m/s] in still water:
    ``λ = U √((m + m_11)(m_22 − m_11) / ((m + m_22)(I_z + m_66)))`` (docs/spec.md §7).

    Raises:
        ValueError: ``m_22 ≤ m_11`` (the straight course is then not unstable).
    """
    m11, m22, m66 = added_mass
    if m22 <= m11:
        raise ValueError(f"no Munk instability: m_22 = {m22} is not above m_11 = {m11}")
    return float(speed * ((mass + m11) * (m22 - m11) / ((mass + m22) * (inertia + m66))) ** 0.5)


__all__ = [
    "STATE_NAMES",
    "AbstractPlanarDamping",
    "DiagonalDamping",
    "PlanarEquations",
    "added_mass_matrix",
    "body_force",
    "coriolis",
    "munk_growth_rate",
    "rigid_body_mass",
    "rotation",
    "water_at_body",
]
