"""Equations of motion of a rigid body translating in a 2-D flow (docs/spec.md §1).

State ``s = (x, y, vx, vy)`` [m, m, m/s, m/s]. With ``v_rel = v − u(x, t)``, ``σ = ‖v_rel‖ + ε``
and coefficients ``(m_ax, m_ay, c_q, c_l) = g(r, σ)``, ``r = ‖x − x₀‖`` (``x₀ = origin``, zero
unless given):

    ``F_h = −(½ ρ A c_q σ + c_l) v_rel``
    ``F_in,i = (ρV + m_a,i) (Du/Dt)_i``      (Morison fluid inertia, only if enabled)
    ``a_i = (F_h,i + F_ext,i + F_in,i) / (M + m_a,i)``
    ``ṡ = (vx, vy, ax, ay)``

The same module serves the ground truth (analytic flow and coefficient laws) and the FHNN model
(a stream-function network and a coefficient network in their place).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from fhnn.physics.body import AbstractCoefficients, Body
from fhnn.physics.flows import AbstractFlow
from fhnn.physics.numerics import safe_norm

Array = jax.Array

SIGMA_EPS = 1e-6


class EquationsOfMotion(eqx.Module):
    """The vector field ``ṡ = f(s, t, F_ext)`` of a floating body.

    Attributes:
        flow: the background flow.
        coefficients: ``(r, σ) ↦ (m_ax, m_ay, c_q, c_l)``.
        mass: dry mass M [kg].
        rho: fluid density ρ [kg/m³].
        area: reference area A [m²].
        volume: displaced volume V [m³] (Morison term only).
        fluid_inertia: include the Morison force ``(ρV + m_a,i)(Du/Dt)_i``.
        eps: ε in ``σ = ‖v_rel‖ + ε`` [m/s].
        origin: the point ``x₀`` [m], shape ``(2,)``, that ``r`` is taken from (None: the
            coordinate origin).
    """

    flow: AbstractFlow
    coefficients: AbstractCoefficients
    mass: float | Array
    rho: float | Array
    area: float | Array
    volume: float | Array = 0.0
    fluid_inertia: bool = eqx.field(static=True, default=False)
    eps: float = SIGMA_EPS
    origin: Array | None = None

    @classmethod
    def of(cls, flow: AbstractFlow, body: Body) -> EquationsOfMotion:
        """The ground-truth equations of ``body`` in ``flow``."""
        return cls(
            flow=flow,
            coefficients=body.coefficients,
            mass=body.mass,
            rho=body.rho,
            area=body.area,
            volume=body.volume,
            fluid_inertia=body.fluid_inertia,
        )

    def radius(self, positions: Array) -> Array:
        """``r = ‖x − x₀‖`` [m] of positions ``(..., 2)`` [m]: what the coefficients see."""
        pos = jnp.asarray(positions)
        if self.origin is not None:
            pos = pos - jax.lax.stop_gradient(self.origin)
        return safe_norm(pos)

    def relative_speed(self, state: Array, t: Array) -> Array:
        """``σ = ‖v − u(x, t)‖ + ε`` [m/s] for one state of shape ``(4,)``."""
        return safe_norm(state[2:] - self.flow.velocity(state[:2], t)) + self.eps

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        """``ṡ`` for one state ``(4,)`` at time ``t`` [s] under ``F_ext = force`` [N], ``(2,)``."""
        pos, vel = state[:2], state[2:]
        # known constants, never learned: no gradient flows into them even when a model holds
        # them as arrays (see fhnn.models.fhnn.build_fhnn)
        mass, rho, area, volume = jax.lax.stop_gradient((self.mass, self.rho, self.area, self.volume))
        u = self.flow.velocity(pos, t)
        v_rel = vel - u
        sigma = safe_norm(v_rel) + self.eps
        coeff = self.coefficients(self.radius(pos), sigma)
        added_mass, c_q, c_l = coeff[:2], coeff[2], coeff[3]
        total = force - (0.5 * rho * area * c_q * sigma + c_l) * v_rel
        if self.fluid_inertia:
            total = total + (rho * volume + added_mass) * self.flow.material_derivative(pos, t)
        accel = total / (mass + added_mass)
        return jnp.concatenate([vel, accel])
