"""An independent NumPy implementation of the ground-truth equations of motion.

Written from docs/spec.md §1–2 separately from the JAX modules (closed-form flows and material
derivatives, scalar code, no autodiff), it serves two purposes: cross-checking the JAX physics in
tests, and driving ``scipy.integrate.solve_ivp`` in the simulator benchmark.

>>> f = reference_vector_field(get_scenario("steady_vortex"))
>>> f(0.0, np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(2))   # ds/dt
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from fhnn.physics.scenarios import (
    NoisyFlow,
    Obstacle,
    Scenario,
    SolidBodyVortex,
    SteadyVortex,
    TimeVaryingVortex,
    Wave,
)

#: ``f(t, s, force) -> ds/dt`` for one state ``s`` of shape ``(4,)``.
ReferenceField = Callable[[float, np.ndarray, np.ndarray], np.ndarray]

EPS = 1e-6


def _lamb_oseen(gamma: float, rc: float) -> Callable[[float, float], tuple[float, float]]:
    def u(x: float, y: float) -> tuple[float, float]:
        r2 = x * x + y * y
        s = r2 / rc**2
        f = 1.0 - s / 2.0 if s < 1e-8 else -math.expm1(-s) / s
        k = gamma / (2.0 * math.pi * rc**2) * f
        return -k * y, k * x

    return u


def _reference_flow(sc: Scenario) -> tuple[Any, Any]:
    """``scenario``'s flow ``(x, y, t) -> (u, v)`` [m/s] and, for a wave, the fluid's material
    acceleration ``(x, y, t) -> (ax, ay)`` [m/s²] (else ``None``)."""
    material = None
    if isinstance(sc, SolidBodyVortex):

        def flow(x: float, y: float, t: float) -> tuple[float, float]:
            return -sc.omega * y, sc.omega * x

    elif isinstance(sc, TimeVaryingVortex):

        def flow(x: float, y: float, t: float) -> tuple[float, float]:
            g = sc.gamma * (1.0 + sc.gamma_modulation * math.sin(2 * math.pi * t / sc.gamma_period))
            return _lamb_oseen(g, sc.core_radius)(x, y)

    elif isinstance(sc, NoisyFlow):
        vortex = _lamb_oseen(sc.gamma, sc.core_radius)
        modes = np.asarray(sc.modes, dtype=float).reshape(-1, 4)

        def flow(x: float, y: float, t: float) -> tuple[float, float]:
            ux, uy = vortex(x, y)
            s = modes[:, 3] * np.sin(modes[:, 0] * x + modes[:, 1] * y + modes[:, 2])
            return ux - float(np.sum(s * modes[:, 1])), uy + float(np.sum(s * modes[:, 0]))

    elif isinstance(sc, SteadyVortex):
        flow = lambda x, y, t: _lamb_oseen(sc.gamma, sc.core_radius)(x, y)  # noqa: E731

    elif isinstance(sc, Obstacle):
        U, R2, k = sc.stream_speed, sc.radius**2, sc.circulation / (2 * math.pi)

        def flow(x: float, y: float, t: float) -> tuple[float, float]:
            r2 = x * x + y * y
            ux = U * (1 - R2 / r2) + 2 * U * R2 * y * y / r2**2 - k * y / r2
            uy = -2 * U * R2 * x * y / r2**2 + k * x / r2
            return ux, uy

    elif isinstance(sc, Wave):
        w = 2 * math.pi / sc.period
        kw = w * w / sc.gravity
        a = sc.amplitude

        def flow(x: float, y: float, t: float) -> tuple[float, float]:
            th = kw * x - w * t
            e = a * w * math.exp(kw * y)
            return e * math.cos(th), e * math.sin(th)

        def material(x: float, y: float, t: float) -> tuple[float, float]:
            th = kw * x - w * t
            e = math.exp(kw * y)
            return a * w * w * e * math.sin(th), -a * w * w * e * math.cos(th) + a * a * w * w * kw * e * e

    else:  # pragma: no cover - every registered scenario is handled above
        raise TypeError(f"no reference implementation for {type(sc).__name__}")
    return flow, material


def reference_vector_field(scenario: Scenario) -> ReferenceField:
    """The equations of motion of ``scenario`` (resolved: noisy modes drawn) in plain NumPy."""
    sc = scenario
    fluid_inertia = isinstance(sc, Wave)
    M, rho, A = sc.mass, sc.rho, sc.area  # type: ignore[attr-defined]
    flow, material = _reference_flow(sc)
    if isinstance(sc, SolidBodyVortex):

        def coeffs(r: float, sigma: float) -> tuple[float, float, float, float]:
            m = sc.m_a_base + sc.m_a_amplitude * math.tanh(sc.m_a_rate * sigma)
            return m, m, sc.c_q, sc.c_l

    else:

        def coeffs(r: float, sigma: float) -> tuple[float, float, float, float]:
            c_q = sc.cq_inf + sc.cq_0 / (1.0 + sigma / sc.cq_sigma_ref)  # type: ignore[attr-defined]
            wall = 1.0 + sc.wall_strength * (sc.radius / r) ** 2 if isinstance(sc, Obstacle) else 1.0
            return sc.m_ax * wall, sc.m_ay * wall, c_q, sc.c_l  # type: ignore[attr-defined]

    def f(t: float, s: np.ndarray, force: np.ndarray) -> np.ndarray:
        x, y, vx, vy = s
        ux, uy = flow(x, y, t)
        rx, ry = vx - ux, vy - uy
        sigma = math.hypot(rx, ry) + EPS
        m_ax, m_ay, c_q, c_l = coeffs(math.hypot(x, y), sigma)
        k = 0.5 * rho * A * c_q * sigma + c_l
        fx, fy = force[0] - k * rx, force[1] - k * ry
        if fluid_inertia:
            dx, dy = material(x, y, t)
            fx += (M + m_ax) * dx  # neutrally buoyant: ρV = M
            fy += (M + m_ay) * dy
        return np.array([vx, vy, fx / (M + m_ax), fy / (M + m_ay)])

    return f


def reference_actuation(params: np.ndarray, t: float) -> np.ndarray:
    """``F_ext(t)`` [N], shape ``(2,)``, for parameters of shape ``(2, 3, 3)``."""
    return np.sum(params[..., 0] * np.sin(2 * math.pi * params[..., 1] * t + params[..., 2]), axis=-1)
