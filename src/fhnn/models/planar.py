"""FHNN for a body that turns (docs/spec.md §7): the 3-DOF equations of
:class:`~fhnn.physics.planar.PlanarEquations` with three learned parts.

- the flow: a :class:`~fhnn.models.fhnn.StreamNet` ψ_θ as for the point body (its far-field linear
  flow included); the water's rotation ω/2 = −½∇²ψ_θ enters the yaw damping;
- the added masses ``(m_11, m_22, m_66) = (m, m, I_z) · softplus(a)``, three positive constants;
- the damping :class:`DampingNet` ``D(ν_r) = diag(d(ν_r))`` with ``d = d_s · softplus(MLP(ν_r / ν_s))``:
  every entry positive, so ``ν_rᵀ D ν_r ≥ 0`` for any weights (dissipative by construction); or,
  with ``damping = "full"``, a full ``D = S (L Lᵀ + K) S`` (``L`` lower triangular, ``K``
  skew-symmetric, both from the MLP; ``S = diag(√d_s)``): coupled axes, still dissipative.

The body's mass, yaw inertia and centre of gravity are known constants of the data set.
"""

from __future__ import annotations

import typing
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, coerce, frozen_config
from fhnn.data.planar import PlanarDataset
from fhnn.models.fhnn import StreamNet
from fhnn.physics.planar import AbstractPlanarDamping, PlanarEquations

Array = jax.Array


@frozen_config
class PlanarModelConfig(Config):
    """Architecture of a :class:`PlanarFHNN`.

    Attributes:
        width, depth: hidden units and layers of the flow and damping nets.
        time_modes: harmonics K of a time-dependent flow's basis in time (as
            :attr:`fhnn.models.fhnn.FHNNConfig.time_modes`).
        init_added_mass: the added masses' start, as fractions of ``(m, m, I_z)``.
        damping: ``"diagonal"`` (one coefficient per axis) or ``"full"`` (a 3 × 3 matrix whose
            symmetric part is positive semi-definite: the axes coupled, e.g. a sway force from
            the yaw rate).
        damping_inputs: what the damping net sees: ``"speeds"`` (``|ν_r| / ν_s`` per entry,
            smoothed within 1e-3 ν_s of zero: a damping even in each of surge, sway and yaw, as a
            hull symmetric fore–aft and port–starboard) or ``"velocity"`` (``ν_r / ν_s``).
    """

    config_name = "planar model"

    width: int = 32
    depth: int = 3
    time_modes: int = 8
    init_added_mass: float = 0.5
    damping: Literal["diagonal", "full"] = "diagonal"
    damping_inputs: Literal["velocity", "speeds"] = "speeds"

    def validate(self) -> None:
        check_positive(self, "width", "depth", "init_added_mass")
        check_nonnegative(self, "time_modes")
        hints = typing.get_type_hints(type(self))
        for name in ("damping", "damping_inputs"):
            coerce(hints[name], getattr(self, name), name)


class DampingNet(AbstractPlanarDamping):
    """``D(ν_r) ν_r`` [N, N, N·m]. Diagonal: ``D = diag(d_s · softplus(MLP(x)))``; full:
    ``D = S (L Lᵀ + K) S`` with ``S = diag(√d_s)``, the MLP's nine outputs giving ``L``'s diagonal
    (through softplus) and lower entries and ``K``'s three skew entries. ``x = ν_r / ν_s``, or with
    ``even`` ``√((ν_r / ν_s)² + 10⁻⁶)`` per entry; ``ν_s`` [m/s, m/s, rad/s] and ``d_s``
    [N·s/m, N·s/m, N·m·s] are data-derived constants, held behind ``stop_gradient``."""

    mlp: eqx.nn.MLP
    nu_scale: Array  # (3,) [m/s, m/s, rad/s]
    d_scale: Array  # (3,)
    even: bool = eqx.field(static=True, default=False)
    full: bool = eqx.field(static=True, default=False)

    def matrix(self, nu_r: Array) -> Array:
        """``D(ν_r)``, shape ``(3, 3)``; its symmetric part is positive semi-definite."""
        nu_s, d_s = jax.lax.stop_gradient((self.nu_scale, self.d_scale))
        x = nu_r / nu_s
        if self.even:
            x = jnp.sqrt(x**2 + 1e-6)
        out = self.mlp(x)
        if not self.full:
            return jnp.diag(d_s * jax.nn.softplus(out))
        lower = jnp.diag(jax.nn.softplus(out[:3]))
        lower = lower.at[jnp.array([1, 2, 2]), jnp.array([0, 0, 1])].set(out[3:6])
        skew = jnp.zeros((3, 3)).at[jnp.array([1, 2, 2]), jnp.array([0, 0, 1])].set(out[6:9])
        root = jnp.sqrt(d_s)
        return root[:, None] * (lower @ lower.T + skew - skew.T) * root[None, :]

    def coefficients(self, nu_r: Array) -> Array:
        """The diagonal of ``D(ν_r)``, shape ``(3,)``, every entry ≥ 0."""
        return jnp.diag(self.matrix(nu_r))

    def __call__(self, nu_r: Array) -> Array:
        return self.matrix(nu_r) @ nu_r


class PlanarFHNN(eqx.Module):
    """The learned vector field ``ṡ = f(s, t, τ)`` of a body that turns; ``s`` shape ``(6,)``,
    ``τ`` the known body-frame forces and moment, shape ``(3,)``."""

    flow: StreamNet
    damping: DampingNet
    mass_raw: Array  # (3,)
    mass: Array  # [kg]
    inertia: Array  # [kg·m²]
    x_g: Array  # [m]

    def added_mass(self) -> Array:
        """``(m_11, m_22, m_66)`` [kg, kg, kg·m²], shape ``(3,)``."""
        scale = jax.lax.stop_gradient(jnp.stack([self.mass, self.mass, self.inertia]))
        return scale * jax.nn.softplus(self.mass_raw)

    def equations(self) -> PlanarEquations:
        """The model as :class:`~fhnn.physics.planar.PlanarEquations`."""
        mass, inertia, x_g = jax.lax.stop_gradient((self.mass, self.inertia, self.x_g))
        return PlanarEquations(
            flow=self.flow,
            damping=self.damping,
            mass=mass,
            inertia=inertia,
            added_mass=self.added_mass(),
            x_g=x_g,
        )

    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        return self.equations()(state, t, force)


def planar_arguments(dataset: PlanarDataset) -> dict[str, Any]:
    """Data-derived arguments of :func:`build_planar_fhnn`: the known body constants, whether the
    flow depends on time, and the scales of the training split."""
    train = dataset.splits["train"]
    states = train.states[train.valid()]
    nu = states[:, 3:]
    pos = states[:, :2]
    return {
        "mass": dataset.mass,
        "inertia": dataset.inertia,
        "x_g": dataset.x_g,
        "time_dependent": dataset.time_dependent,
        "length_scale": float(np.sqrt(np.mean(np.sum(pos**2, axis=-1)))),
        "speed_scale": float(np.sqrt(np.mean(nu[:, :2] ** 2))),
        "rate_scale": float(np.sqrt(np.mean(nu[:, 2] ** 2))),
        "time_scale": float(np.max(train.t[train.valid()])),
    }


def build_planar_fhnn(
    config: PlanarModelConfig,
    *,
    mass: float,
    inertia: float,
    x_g: float,
    time_dependent: bool,
    length_scale: float,
    speed_scale: float,
    rate_scale: float,
    time_scale: float,
    key: Array,
) -> PlanarFHNN:
    """A :class:`PlanarFHNN` with fresh weights drawn from ``key``.

    Args:
        config: the architecture.
        mass, inertia, x_g: the body's known constants [kg, kg·m², m].
        time_dependent: whether ψ_θ depends on time.
        length_scale: typical |x| [m]; speed_scale: typical body speed [m/s]; rate_scale: typical
            yaw rate [rad/s]; time_scale: the training window [s].
        key: PRNG key.
    """
    k_flow, k_damp = jax.random.split(key)
    modes = config.time_modes if time_dependent else 0
    n_in = 3 if time_dependent and not modes else 2
    mlp = eqx.nn.MLP(n_in, 1 + 2 * modes, config.width, config.depth, activation=jnp.tanh, key=k_flow)
    mlp = eqx.tree_at(lambda m: m.layers[-1].weight, mlp, jnp.zeros_like(mlp.layers[-1].weight))
    flow = StreamNet(
        mlp=mlp,
        length_scale=jnp.asarray(float(length_scale)),
        psi_scale=jnp.asarray(float(speed_scale * length_scale)),
        time_scale=jnp.asarray(float(time_scale)),
        uses_time=time_dependent,
        quadratic=jnp.zeros(3),
        linear=jnp.zeros(2),
        time_modes=modes,
    )
    full = config.damping == "full"
    damp_mlp = eqx.nn.MLP(3, 9 if full else 3, config.width, config.depth, activation=jnp.tanh, key=k_damp)
    last = damp_mlp.layers[-1]
    damp_mlp = eqx.tree_at(lambda m: m.layers[-1].weight, damp_mlp, last.weight * 0.1)
    # damping scales: a body of this mass stopping in about a second
    d_scale = jnp.asarray([mass, mass, inertia], float)
    damping = DampingNet(
        mlp=damp_mlp,
        nu_scale=jnp.asarray([speed_scale, speed_scale, max(rate_scale, 1e-6)], float),
        d_scale=d_scale,
        even=config.damping_inputs == "speeds",
        full=full,
    )
    raw = float(np.log(np.expm1(config.init_added_mass)))
    return PlanarFHNN(
        flow=flow,
        damping=damping,
        mass_raw=jnp.full(3, raw),
        mass=jnp.asarray(float(mass)),
        inertia=jnp.asarray(float(inertia)),
        x_g=jnp.asarray(float(x_g)),
    )


__all__ = ["DampingNet", "PlanarFHNN", "PlanarModelConfig", "build_planar_fhnn", "planar_arguments"]
