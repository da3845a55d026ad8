"""A turning body driven by logged controls (rudder angle, propeller speed, …) instead of known
forces: :class:`~fhnn.models.planar.PlanarFHNN` with a learned actuator map.

``τ = A(ν_r, c)`` [N, N, N·m] maps the relative velocity ``ν_r`` (body frame, as the damping sees
it) and the controls ``c`` (up to three, in the table's units) to the body-frame forces and moment
the model's equations receive. ``A = f_s ⊙ MLP((ν_r / ν_s, (c − c̄) / c_σ))``: ``ν_s`` is the damping's
velocity scale, ``c̄`` and ``c_σ`` the controls' mean and spread over the training split, and
``f_s = (m ν_s, m ν_s, I_z r_s)`` per second; all held behind ``stop_gradient``. The map is not
constrained: a propeller adds energy, a rudder at a drift angle takes it out.

The controls reach the model where known forces would (the data set's ``forces`` channel,
linearly interpolated between samples; :mod:`fhnn.data.planar_controls`), so data sets, forecasts
and one-step losses of :mod:`fhnn.data.planar`, :mod:`fhnn.evaluation.planar` and
:mod:`fhnn.training.planar` apply unchanged.

Without known forces the data do not fix the added masses: a change of the total inertia is
matched by one of the learned forces (the map depends on ``ν_r`` freely), so the learned
``(m_11, m_22, m_66)`` are fit parameters, not measurements.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.planar import PlanarDataset
from fhnn.models.planar import PlanarFHNN, PlanarModelConfig, build_planar_fhnn, planar_arguments
from fhnn.physics.planar import water_at_body

Array = jax.Array
#: The most control columns a data set carries (the width of the forces channel).
MAX_CONTROLS = 3


class ActuatorNet(eqx.Module):
    """``A(ν_r, c)`` [N, N, N·m], shape ``(3,)``, for ``ν_r`` ``(3,)`` [m/s, m/s, rad/s] and the
    controls ``c`` ``(n_controls,)`` (module docstring)."""

    mlp: eqx.nn.MLP
    nu_scale: Array  # (3,) [m/s, m/s, rad/s]
    control_mean: Array  # (n_controls,)
    control_scale: Array  # (n_controls,)
    force_scale: Array  # (3,) [N, N, N·m]

    def __call__(self, nu_r: Array, controls: Array) -> Array:
        nu_s, c_mean, c_s, f_s = jax.lax.stop_gradient(
            (self.nu_scale, self.control_mean, self.control_scale, self.force_scale)
        )
        x = jnp.concatenate([nu_r / nu_s, (controls - c_mean) / c_s])
        return f_s * self.mlp(x)


class ActuatedPlanarFHNN(eqx.Module):
    """The learned vector field ``ṡ = f(s, t, c)`` of a body that turns under logged controls;
    ``s`` shape ``(6,)``, ``c`` the controls padded to shape ``(3,)`` (entries past
    ``n_controls`` ignored)."""

    body: PlanarFHNN
    actuator: ActuatorNet
    n_controls: int = eqx.field(static=True)

    def added_mass(self) -> Array:
        """``(m_11, m_22, m_66)`` [kg, kg, kg·m²], shape ``(3,)`` (not fixed by the data: module
        docstring)."""
        return self.body.added_mass()

    def force(self, state: Array, t: Array, controls: Array) -> Array:
        """The actuators' body-frame forces and moment ``τ`` [N, N, N·m], shape ``(3,)``."""
        nu_r = state[3:] - water_at_body(self.body.flow, state[:3], t)
        return self.actuator(nu_r, controls[: self.n_controls])

    def __call__(self, state: Array, t: Array, controls: Array) -> Array:
        return self.body(state, t, self.force(state, t, controls))


def control_statistics(dataset: PlanarDataset, n_controls: int) -> tuple[np.ndarray, np.ndarray]:
    """The controls' mean and spread over the training split's own samples, each
    ``(n_controls,)``; a constant control's spread is 1."""
    train = dataset.splits["train"]
    values = train.forces[train.valid()][:, :n_controls]
    spread = np.std(values, axis=0)
    return np.mean(values, axis=0), np.where(spread > 0, spread, 1.0)


def build_actuated_fhnn(
    config: PlanarModelConfig, dataset: PlanarDataset, n_controls: int, *, key: Array
) -> ActuatedPlanarFHNN:
    """An :class:`ActuatedPlanarFHNN` with fresh weights drawn from ``key``: the body as
    :func:`~fhnn.models.planar.build_planar_fhnn` makes it from ``dataset``, the actuator an MLP
    of ``config``'s width and depth whose last layer starts at a tenth of its drawn weights.

    Raises:
        ValueError: ``n_controls`` is not 1, 2 or 3.
    """
    if not 1 <= n_controls <= MAX_CONTROLS:
        raise ValueError(f"n_controls must be 1 to {MAX_CONTROLS}, got {n_controls}")
    k_body, k_act = jax.random.split(key)
    args = planar_arguments(dataset)
    body = build_planar_fhnn(config, **args, key=k_body)
    mlp = eqx.nn.MLP(3 + n_controls, 3, config.width, config.depth, activation=jnp.tanh, key=k_act)
    mlp = eqx.tree_at(lambda m: m.layers[-1].weight, mlp, mlp.layers[-1].weight * 0.1)
    mean, spread = control_statistics(dataset, n_controls)
    nu_scale = body.damping.nu_scale
    force_scale = jnp.asarray([args["mass"], args["mass"], args["inertia"]], float) * nu_scale
    actuator = ActuatorNet(
        mlp=mlp,
        nu_scale=nu_scale,
        control_mean=jnp.asarray(mean, float),
        control_scale=jnp.asarray(spread, float),
        force_scale=force_scale,
    )
    return ActuatedPlanarFHNN(body=body, actuator=actuator, n_controls=n_controls)


__all__ = ["MAX_CONTROLS", "ActuatedPlanarFHNN", "ActuatorNet", "build_actuated_fhnn", "control_statistics"]
