"""Background flows of a 2-D incompressible fluid, each defined by a stream function.

Convention (docs/spec.md §1): ``u = ∇⊥ψ = (∂ψ/∂y, −∂ψ/∂x)``, so a vortex with circulation Γ > 0 turns
counter-clockwise and ``∇·u = 0`` holds identically.

Every flow is an :class:`AbstractFlow` (an Equinox module): ``stream(xy, t)`` gives ψ [m²/s] at one
point ``xy`` (shape ``(2,)``, metres) and time ``t`` (s); ``velocity(xy, t)`` gives ``u`` [m/s],
shape ``(2,)``. The analytic flows here implement ``velocity`` in closed form; the default (used by
learned flows) differentiates ``stream``. The velocity gradient and the material derivative
``Du/Dt = ∂u/∂t + (u·∇)u`` (needed by the Morison inertia force) come from automatic
differentiation of ``velocity``, which is exact for these closed forms.
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import exp1

from fhnn.physics.numerics import safe_norm_squared

Array = jax.Array

EULER_GAMMA = 0.5772156649015329


class AbstractFlow(eqx.Module):
    """A 2-D incompressible flow given by a stream function ψ(x, y, t)."""

    @property
    def time_dependent(self) -> bool:
        """Whether the flow changes in time (a model of it then needs ψ(x, y, t))."""
        return False

    @abc.abstractmethod
    def stream(self, xy: Array, t: Array) -> Array:
        """Stream function ψ [m²/s] at ``xy`` (shape ``(2,)``, m) and time ``t`` [s]; scalar."""

    def in_fluid(self, points: np.ndarray) -> np.ndarray:
        """Whether each of ``points`` ``(P, 2)`` [m] lies in the fluid, ``(P,)`` bool: false inside
        a solid body the flow goes around, where its formula is a continuation no body meets and
        no data can inform (evaluation leaves such points out). Everywhere true but for a flow
        with a body in it."""
        return np.ones(np.shape(points)[0], dtype=bool)

    def velocity(self, xy: Array, t: Array) -> Array:
        """Flow velocity ``u = (∂ψ/∂y, −∂ψ/∂x)`` [m/s], shape ``(2,)``."""
        g = jax.grad(self.stream)(jnp.asarray(xy, float), jnp.asarray(t, float))
        return jnp.stack([g[1], -g[0]])

    def velocity_gradient(self, xy: Array, t: Array) -> Array:
        """``∂u_i/∂x_j`` [1/s], shape ``(2, 2)``."""
        return jax.jacfwd(self.velocity)(jnp.asarray(xy, float), jnp.asarray(t, float))

    def material_derivative(self, xy: Array, t: Array) -> Array:
        """``Du/Dt = ∂u/∂t + (u·∇)u`` [m/s²], shape ``(2,)``.

        Computed as the derivative of ``u`` along the direction ``(u, 1)`` in ``(x, y, t)``, one
        forward-mode product.
        """
        xy = jnp.asarray(xy, float)
        t = jnp.asarray(t, float)
        u = self.velocity(xy, t)
        _, du = jax.jvp(self.velocity, (xy, t), (u, jnp.ones_like(t)))
        return du


@eqx.filter_jit
def velocity_field(flow: AbstractFlow, points: Array, times: Array) -> Array:
    """``flow``'s velocity [m/s] at every one of ``points`` (shape ``(P, 2)``, m) at every one of
    ``times`` (shape ``(T,)``, s): shape ``(T, P, 2)``. One compiled program per flow type and
    shape (an eager ``vmap`` dispatches and compiles each primitive on its own: ~150 small
    programs, 1.3 s for a figure's two grids, against ~0.3 s)."""
    return jax.vmap(lambda t: jax.vmap(flow.velocity, in_axes=(0, None))(points, t))(times)


class StillWater(AbstractFlow):
    """No background flow: ψ = 0."""

    def stream(self, xy: Array, t: Array) -> Array:
        return jnp.zeros((), dtype=jnp.result_type(xy, float))

    def velocity(self, xy: Array, t: Array) -> Array:
        return jnp.zeros(2, dtype=jnp.result_type(xy, float))


class LambOseenVortex(AbstractFlow):
    """Lamb–Oseen vortex at the origin, optionally with a sinusoidally modulated circulation.

    ``ψ(r) = −(Γ/4π) [ln(r²/r_c²) + E1(r²/r_c²)]``, ``u_θ = Γ/(2πr) (1 − exp(−r²/r_c²))``,
    smooth at ``r = 0``. With ``modulation = m ≠ 0`` the circulation is
    ``Γ(t) = Γ (1 + m sin(2π t / period))``.

    Attributes:
        gamma: circulation Γ [m²/s] (Γ > 0 turns counter-clockwise).
        core_radius: r_c [m].
        modulation: relative amplitude m of Γ(t) (0 for a steady vortex).
        period: period of Γ(t) [s].
    """

    gamma: float
    core_radius: float
    modulation: float = 0.0
    period: float = 20.0

    @property
    def time_dependent(self) -> bool:
        return self.modulation != 0.0

    def circulation(self, t: Array) -> Array:
        """Γ(t) [m²/s]."""
        return self.gamma * (1.0 + self.modulation * jnp.sin(2.0 * math.pi * t / self.period))

    def stream(self, xy: Array, t: Array) -> Array:
        s = safe_norm_squared(xy) / self.core_radius**2
        small = s < 1e-2
        s_big = jnp.where(small, 1.0, s)
        # ln s + E1(s) = −γ − Σ_k (−s)^k / (k·k!) = −γ + s − s²/4 + s³/18 − … (smooth at s = 0);
        # six terms leave < 1e-18 at the switch s = 1e-2
        series = -EULER_GAMMA + s * (
            1.0 + s * (-1.0 / 4.0 + s * (1.0 / 18.0 + s * (-1.0 / 96.0 + s * (1.0 / 600.0 - s / 4320.0))))
        )
        closed = jnp.log(s_big) + exp1(s_big)
        bracket = jnp.where(small, series, closed)
        return -self.circulation(t) / (4.0 * math.pi) * bracket

    def velocity(self, xy: Array, t: Array) -> Array:
        s = safe_norm_squared(xy) / self.core_radius**2
        small = s < 1e-2
        s_big = jnp.where(small, 1.0, s)
        # f(s) = (1 − e^{−s}) / s = Σ_k (−s)^k / (k+1)!, series near 0 (< 1e-18 at s = 1e-2)
        series = 1.0 + s * (
            -1.0 / 2.0
            + s * (1.0 / 6.0 + s * (-1.0 / 24.0 + s * (1.0 / 120.0 + s * (-1.0 / 720.0 + s / 5040.0))))
        )
        f = jnp.where(small, series, -jnp.expm1(-s_big) / s_big)
        scale = self.circulation(t) / (2.0 * math.pi * self.core_radius**2) * f
        return scale * jnp.stack([-xy[1], xy[0]])


class FourierModes(AbstractFlow):
    """A frozen sum of plane-wave stream-function modes ``ψ = Σ_j b_j cos(k_j·x + φ_j)``.

    Attributes:
        kx, ky: wave-vector components [rad/m], shape ``(J,)``.
        phase: φ_j [rad], shape ``(J,)``.
        amp: b_j [m²/s], shape ``(J,)``.
    """

    kx: Array
    ky: Array
    phase: Array
    amp: Array

    def _arg(self, xy: Array) -> Array:
        return self.kx * xy[0] + self.ky * xy[1] + self.phase

    def stream(self, xy: Array, t: Array) -> Array:
        return jnp.sum(self.amp * jnp.cos(self._arg(xy)))

    def velocity(self, xy: Array, t: Array) -> Array:
        s = self.amp * jnp.sin(self._arg(xy))
        return jnp.stack([-jnp.sum(s * self.ky), jnp.sum(s * self.kx)])


class SuperposedFlow(AbstractFlow):
    """The sum of several flows (stream functions and velocities add)."""

    parts: tuple[AbstractFlow, ...]

    @property
    def time_dependent(self) -> bool:
        return any(p.time_dependent for p in self.parts)

    def in_fluid(self, points: np.ndarray) -> np.ndarray:
        return np.logical_and.reduce([p.in_fluid(points) for p in self.parts])

    def stream(self, xy: Array, t: Array) -> Array:
        return sum(p.stream(xy, t) for p in self.parts)  # type: ignore[return-value]

    def velocity(self, xy: Array, t: Array) -> Array:
        return sum(p.velocity(xy, t) for p in self.parts)  # type: ignore[return-value]


class CylinderFlow(AbstractFlow):
    """Uniform stream past a circular cylinder at the origin, with circulation.

    ``ψ = U y (1 − R²/r²) − (Γc/2π) ln(r/R)``; the cylinder ``r = R`` is the streamline ψ = 0.

    Attributes:
        stream_speed: U∞ [m/s], along +x far from the cylinder.
        radius: R [m].
        circulation: Γc [m²/s] (counter-clockwise for Γc > 0).
    """

    stream_speed: float
    radius: float
    circulation: float

    def in_fluid(self, points: np.ndarray) -> np.ndarray:
        """Outside the cylinder: ``r ≥ R``."""
        return np.hypot(*np.asarray(points, float).T) >= self.radius

    def stream(self, xy: Array, t: Array) -> Array:
        r2 = safe_norm_squared(xy)
        return self.stream_speed * xy[1] * (1.0 - self.radius**2 / r2) - self.circulation / (
            4.0 * math.pi
        ) * jnp.log(r2 / self.radius**2)

    def velocity(self, xy: Array, t: Array) -> Array:
        x, y = xy[0], xy[1]
        r2 = safe_norm_squared(xy)
        U, R2, k = self.stream_speed, self.radius**2, self.circulation / (2.0 * math.pi)
        ux = U * (1.0 - R2 / r2) + 2.0 * U * R2 * y * y / r2**2 - k * y / r2
        uy = -2.0 * U * R2 * x * y / r2**2 + k * x / r2
        return jnp.stack([ux, uy])


class DeepWaterWave(AbstractFlow):
    """Linear deep-water progressive wave in a vertical plane (``y ≤ 0`` under the mean surface).

    ``ψ = (aω/k) e^{k y} cos(k x − ω t)``, ``ω = 2π/T``, ``k = ω²/g``, so
    ``u = aω e^{k y} (cos θ, sin θ)`` with ``θ = k x − ω t``.

    Attributes:
        amplitude: a [m].
        period: T [s].
        gravity: g [m/s²].
    """

    amplitude: float
    period: float
    gravity: float = 9.81

    @property
    def time_dependent(self) -> bool:
        return True

    @property
    def omega(self) -> float:
        return 2.0 * math.pi / self.period

    @property
    def wavenumber(self) -> float:
        return self.omega**2 / self.gravity

    def stream(self, xy: Array, t: Array) -> Array:
        k, w = self.wavenumber, self.omega
        return self.amplitude * w / k * jnp.exp(k * xy[1]) * jnp.cos(k * xy[0] - w * t)

    def velocity(self, xy: Array, t: Array) -> Array:
        k, w = self.wavenumber, self.omega
        theta = k * xy[0] - w * t
        speed = self.amplitude * w * jnp.exp(k * xy[1])
        return speed * jnp.stack([jnp.cos(theta), jnp.sin(theta)])


class SolidBodyRotation(AbstractFlow):
    """Solid-body rotation ``u = Ω(−y, x)``, ``ψ = −(Ω/2)(x² + y²)``.

    Attributes:
        omega: angular velocity Ω [1/s] (counter-clockwise for Ω > 0).
    """

    omega: float

    def stream(self, xy: Array, t: Array) -> Array:
        return -0.5 * self.omega * (xy[0] ** 2 + xy[1] ** 2)

    def velocity(self, xy: Array, t: Array) -> Array:
        return self.omega * jnp.stack([-xy[1], xy[0]])
