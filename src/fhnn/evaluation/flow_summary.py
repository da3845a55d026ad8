"""A flow in a few numbers: for a vortex-like flow its centre, circulation and core radius (a
Lamb–Oseen vortex fitted by least squares); otherwise its speed range and where its vorticity
peaks. What ``fhnn inspect`` prints beside ``flow.nc``."""

from __future__ import annotations

import dataclasses
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from fhnn.data.dataset import Dataset
from fhnn.evaluation.recovery import flow_grid, window_times
from fhnn.physics.flows import AbstractFlow

Array = jax.Array

#: The share of the flow's velocity variance a fitted vortex must explain for the flow to be
#: summarised as one.
VORTEX_R2 = 0.9


@dataclasses.dataclass(frozen=True)
class FlowSummary:
    """A learned flow's summary over the training data's region (:func:`summarise_flow`).

    Attributes:
        vortex: whether a Lamb–Oseen vortex explains at least :data:`VORTEX_R2` of the velocity's
            variance about its mean.
        explained: that share (R²) for the best-fitting vortex.
        centre: the vortex's centre [m], ``(2,)``.
        circulation: its circulation Γ [m²/s] (positive: counter-clockwise).
        core_radius: its core radius r_c [m] (``u_θ = Γ/(2πr)(1 − exp(−r²/r_c²))``).
        speed_range: the least and greatest speed [m/s] over the region.
        vorticity_peak: where ``|ω|`` is greatest [m], ``(2,)``, and ``peak_vorticity`` ω there [1/s].
    """

    vortex: bool
    explained: float
    centre: tuple[float, float]
    circulation: float
    core_radius: float
    speed_range: tuple[float, float]
    vorticity_peak: tuple[float, float]
    peak_vorticity: float

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def lamb_oseen(params: Array, xy: Array) -> Array:
    """Velocity ``(P, 2)`` [m/s] at ``xy`` ``(P, 2)`` of a Lamb–Oseen vortex with
    ``params = (x₀, y₀, Γ, log r_c)``."""
    d = xy - params[:2]
    r2 = jnp.sum(d**2, axis=-1) + 1e-30
    core2 = jnp.exp(2.0 * params[3])
    # u_θ / r = Γ/(2πr²)(1 − exp(−r²/r_c²)): finite at the centre (→ Γ/(2π r_c²))
    rate = params[2] / (2.0 * jnp.pi) * -jnp.expm1(-r2 / core2) / r2
    return rate[:, None] * jnp.stack([-d[:, 1], d[:, 0]], axis=-1)


@eqx.filter_jit
def _fields(flow: AbstractFlow, xy: Array, t: Array) -> tuple[Array, Array]:
    """Velocity ``(P, 2)`` and vorticity ``(P,)`` of ``flow`` at ``xy`` at time ``t``."""

    def one(p: Array) -> tuple[Array, Array]:
        grad = flow.velocity_gradient(p, t)  # ∂u_i/∂x_j
        return flow.velocity(p, t), grad[1, 0] - grad[0, 1]

    return jax.vmap(one)(xy)


def summarise_flow(flow: AbstractFlow, dataset: Dataset, *, t: float | None = None) -> FlowSummary:
    """Summarise ``flow`` over :func:`~fhnn.evaluation.recovery.flow_grid` of ``dataset`` at the
    time ``t`` [s] (default: the middle of the training data's window).

    The vortex is fitted by Levenberg–Marquardt (optimistix) from the peak of ``|ω|``, with a
    circulation and core radius read off the azimuthal velocity about it.
    """
    points = flow_grid(dataset)
    when = float(np.median(window_times(dataset, 3))) if t is None else float(t)
    u, omega = (np.asarray(a) for a in _fields(flow, jnp.asarray(points), jnp.asarray(when)))
    speed = np.hypot(u[:, 0], u[:, 1])
    peak = int(np.argmax(np.abs(omega)))
    d = points - points[peak]
    r = np.hypot(d[:, 0], d[:, 1])
    u_theta = (d[:, 0] * u[:, 1] - d[:, 1] * u[:, 0]) / np.maximum(r, 1e-12)
    far = r >= np.median(r)
    start = jnp.asarray(
        [
            *points[peak],
            2.0 * np.pi * float(np.median(r[far] * u_theta[far])),
            np.log(max(float(np.median(r)) / 2.0, 1e-6)),
        ]
    )
    xy, target = jnp.asarray(points), jnp.asarray(u)

    def residual(params: Array, _: Any) -> Array:
        return (lamb_oseen(params, xy) - target).ravel()

    solution = optx.least_squares(
        residual, optx.LevenbergMarquardt(rtol=1e-10, atol=1e-12), start, max_steps=400, throw=False
    )
    params = np.asarray(solution.value)
    misfit = np.sum((np.asarray(lamb_oseen(jnp.asarray(params), xy)) - u) ** 2)
    spread = np.sum((u - u.mean(axis=0)) ** 2)
    explained = float(1.0 - misfit / max(spread, 1e-300)) if np.all(np.isfinite(params)) else 0.0
    return FlowSummary(
        vortex=explained >= VORTEX_R2,
        explained=explained,
        centre=(float(params[0]), float(params[1])),
        circulation=float(params[2]),
        core_radius=float(np.exp(params[3])),
        speed_range=(float(speed.min()), float(speed.max())),
        vorticity_peak=(float(points[peak, 0]), float(points[peak, 1])),
        peak_vorticity=float(omega[peak]),
    )
