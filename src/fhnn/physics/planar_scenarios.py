"""Scenarios of a body that turns (docs/spec.md §7): an elongated body (``m_11 ≠ m_22``) with
body-frame thrusters in the Lamb–Oseen vortex of §2.1, steady or with the circulation of §2.2.

Each is a :class:`PlanarScenario`, a frozen configuration; :data:`PLANAR_SCENARIOS` names them and
:func:`get_planar_scenario` builds one with any parameter changed.
"""

from __future__ import annotations

import math
from typing import Any

import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.errors import ConfigError
from fhnn.physics.actuation import N_MODES
from fhnn.physics.body import ReynoldsDrag
from fhnn.physics.flows import AbstractFlow, LambOseenVortex
from fhnn.physics.planar import DiagonalDamping, PlanarEquations


@frozen_config
class PlanarScenario(Config):
    """An elongated body with body-frame thrusters in a Lamb–Oseen vortex.

    Attributes:
        gamma: circulation Γ [m²/s]; core_radius: r_c [m].
        gamma_modulation: relative amplitude of Γ(t) (0: steady); gamma_period: its period [s].
        mass: m [kg]; inertia: I_z [kg·m²] about the tracked point; x_g: centre of gravity
            ahead of it [m].
        added_mass: (m_11, m_22, m_66) [kg, kg, kg·m²].
        linear_damping: (c_l,u, c_l,v, c_l,r) [N·s/m, N·s/m, N·m·s].
        areas: (A_u, A_v) [m²] of the quadratic drag ``½ ρ A c_q(σ) σ``, ``c_q(σ) = 0.6 + 0.4 /
            (1 + σ/0.2)`` as in §1; yaw_quadratic: c_q,r [N·m·s²].
        thrust: the largest amplitude of the thrusters' sinusoids per axis, (X [N], Y [N],
            N [N·m]); each axis sums three sinusoids with amplitudes ~ U(0, thrust), frequencies
            ~ U(0.05, 0.5) Hz and phases ~ U(0, 2π), in the body frame.
        r0_min, r0_max: the start's distance from the vortex centre [m], uniform.
        speed_std: the start's body-frame velocity, normal, per axis [m/s];
        yaw_rate_std: the start's yaw rate, normal [rad/s]. The heading starts uniform.
    """

    gamma: float = 5.0
    core_radius: float = 1.0
    gamma_modulation: float = 0.0
    gamma_period: float = 20.0
    mass: float = 10.0
    inertia: float = 1.0
    x_g: float = 0.0
    added_mass: tuple[float, float, float] = (1.5, 9.0, 0.6)
    linear_damping: tuple[float, float, float] = (2.0, 6.0, 0.5)
    areas: tuple[float, float] = (0.01, 0.05)
    yaw_quadratic: float = 0.3
    thrust: tuple[float, float, float] = (1.0, 0.5, 0.1)
    r0_min: float = 0.5
    r0_max: float = 3.0
    speed_std: float = 0.2
    yaw_rate_std: float = 0.3

    def validate(self) -> None:
        check_positive(self, "core_radius", "gamma_period", "mass", "inertia", "r0_max")
        check_nonnegative(self, "gamma_modulation", "yaw_quadratic", "r0_min", "speed_std", "yaw_rate_std")
        for name, size in (("added_mass", 3), ("linear_damping", 3), ("areas", 2), ("thrust", 3)):
            value = getattr(self, name)
            if len(value) != size or any(not math.isfinite(v) or v < 0 for v in value):
                raise ConfigError(f"{name} must be {size} finite numbers >= 0, got {value!r}")
        if self.r0_min > self.r0_max:
            raise ConfigError(f"r0_min = {self.r0_min} is above r0_max = {self.r0_max}")

    def flow(self) -> AbstractFlow:
        """The vortex: Γ(t) = Γ (1 + m sin(2π t / period))."""
        return LambOseenVortex(self.gamma, self.core_radius, self.gamma_modulation, self.gamma_period)

    def damping(self) -> DiagonalDamping:
        """The body's damping (docs/spec.md §7)."""
        return DiagonalDamping(
            linear=self.linear_damping,
            areas=self.areas,
            quadratic=ReynoldsDrag(c_inf=0.6, c_0=0.4, sigma_ref=0.2),
            yaw_quadratic=self.yaw_quadratic,
        )

    def equations(self) -> PlanarEquations:
        """The true equations of motion."""
        return PlanarEquations(
            flow=self.flow(),
            damping=self.damping(),
            mass=self.mass,
            inertia=self.inertia,
            added_mass=jnp.asarray(self.added_mass, float),
            x_g=self.x_g,
        )

    def sample_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` starts ``(x, y, ψ, u, v, r)``, shape ``(n, 6)``."""
        r0 = rng.uniform(self.r0_min, self.r0_max, n)
        angle = rng.uniform(0.0, 2.0 * math.pi, n)
        heading = rng.uniform(-math.pi, math.pi, n)
        nu = rng.normal(0.0, 1.0, (n, 3)) * np.array([self.speed_std, self.speed_std, self.yaw_rate_std])
        return np.column_stack([r0 * np.cos(angle), r0 * np.sin(angle), heading, nu])

    def sample_thrust(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` thruster programmes, shape ``(n, 3, 3, 3)``: ``[axis (X, Y, N), mode, (amplitude,
        frequency [Hz], phase [rad])]`` (:func:`fhnn.physics.actuation.actuation_force`)."""
        shape = (n, 3, N_MODES)
        amp = rng.uniform(0.0, 1.0, shape) * np.asarray(self.thrust)[None, :, None]
        return np.stack([amp, rng.uniform(0.05, 0.5, shape), rng.uniform(0.0, 2.0 * math.pi, shape)], -1)


#: The named scenarios of a body that turns: name → the parameters that differ from the defaults.
PLANAR_SCENARIOS: dict[str, dict[str, Any]] = {
    "turning_vortex": {},
    "turning_time_varying_vortex": {"gamma_modulation": 0.3},
}


def get_planar_scenario(name: str, **params: Any) -> PlanarScenario:
    """The scenario ``name`` of :data:`PLANAR_SCENARIOS`, with ``params`` changed.

    Raises:
        ConfigError: an unknown name or parameter, or a value out of range.
    """
    if name not in PLANAR_SCENARIOS:
        raise ConfigError(f"unknown turning scenario {name!r}; known: {', '.join(PLANAR_SCENARIOS)}")
    return PlanarScenario(**{**PLANAR_SCENARIOS[name], **params})


__all__ = ["PLANAR_SCENARIOS", "PlanarScenario", "get_planar_scenario"]
