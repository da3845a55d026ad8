"""What a turning body's model learned, in numbers a user can read: the added masses and the
damping over the relative velocities the data cover.

The covered relative velocities are the training split's states with the learned flow taken out,
``ν_r = ν − R(ψ)ᵀ u(x, y, t)`` (:func:`fhnn.physics.planar.water_at_body` of the model's flow), so
they need no truth and serve an imported table as well as a simulation. Where the data set has a
truth, each learned quantity stands beside the true one at the same inputs.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.planar import PlanarDataset
from fhnn.models.planar import PlanarFHNN
from fhnn.physics.planar import water_at_body

#: The added masses' names and units, in the model's order.
MASSES = (("m_11", "kg"), ("m_22", "kg"), ("m_66", "kg·m²"))
#: Per axis: the relative velocity's name and unit, the damping force's name and unit.
AXES = (("u_r", "m/s", "X_d", "N"), ("v_r", "m/s", "Y_d", "N"), ("r_r", "rad/s", "N_d", "N·m"))


def covered_relative_velocities(
    model: PlanarFHNN, dataset: PlanarDataset, max_points: int = 2000
) -> np.ndarray:
    """The relative velocities ``ν_r`` [m/s, m/s, rad/s] of the training split's states under the
    model's learned flow, ``(P, 3)``: an even subsample of at most ``max_points`` of its samples.

    Raises:
        ValueError: ``max_points`` is below 1.
    """
    if max_points < 1:
        raise ValueError(f"max_points must be at least 1, got {max_points}")
    train = dataset.splits["train"]
    valid = train.valid()
    states, times = train.states[valid], train.t[valid]
    keep = np.unique(np.linspace(0, states.shape[0] - 1, min(max_points, states.shape[0])).astype(int))
    s, t = jnp.asarray(states[keep]), jnp.asarray(times[keep])
    water = jax.vmap(lambda st, ti: water_at_body(model.flow, st[:3], ti))(s, t)
    return np.asarray(s[:, 3:] - water)


def damping_samples(
    model: PlanarFHNN, dataset: PlanarDataset, max_points: int = 2000
) -> dict[str, np.ndarray]:
    """The learned damping at :func:`covered_relative_velocities`: per axis the relative velocity
    (``u_r, v_r, r_r``), the damping force and moment ``X_d, Y_d, N_d`` [N, N, N·m] (``D(ν_r) ν_r``)
    and the diagonal coefficients ``d_11, d_22, d_66`` [N·s/m, N·s/m, N·m·s]; with a truth also
    ``true_X_d, true_Y_d, true_N_d`` at the same ``ν_r``. Each ``(P,)``."""
    nu_r = covered_relative_velocities(model, dataset, max_points)
    x = jnp.asarray(nu_r)
    matrix = np.asarray(jax.vmap(model.damping.matrix)(x))  # D(ν_r): the force and its diagonal from one pass
    force = np.einsum("pij,pj->pi", matrix, nu_r)
    coefficients = np.diagonal(matrix, axis1=1, axis2=2)
    out: dict[str, np.ndarray] = {}
    for i, axis in enumerate(AXES):
        out[axis[0]] = nu_r[:, i]
    for i, axis in enumerate(AXES):
        out[axis[2]] = force[:, i]
    for i, name in enumerate(("d_11", "d_22", "d_66")):
        out[name] = coefficients[:, i]
    if dataset.has_truth:
        true = np.asarray(jax.vmap(dataset.truth().damping())(x))
        for i, (_, _, name, _) in enumerate(AXES):
            out[f"true_{name}"] = true[:, i]
    return out


def coefficient_rows(
    model: PlanarFHNN, dataset: PlanarDataset, samples: dict[str, np.ndarray]
) -> list[dict[str, Any]]:
    """One row per learned quantity: the added masses (``value``) and per axis the damping over
    ``samples`` (:func:`damping_samples`): its diagonal coefficient's least and largest value
    (``low``, ``high``) and, with a truth, the damping force's relative L2 error (``rel_error``).
    A mass's row has its ``true`` value and ``rel_error`` where the data set has a truth."""
    learned = np.asarray(model.added_mass())
    true = np.asarray(dataset.params["added_mass"], float) if dataset.has_truth else None
    rows: list[dict[str, Any]] = []
    for i, (name, unit) in enumerate(MASSES):
        row: dict[str, Any] = {"name": name, "unit": unit, "value": float(learned[i])}
        if true is not None:
            row |= {"true": float(true[i]), "rel_error": float(abs(learned[i] - true[i]) / true[i])}
        rows.append(row)
    units = ("N·s/m", "N·s/m", "N·m·s")
    for (speed, _, force, _), coef, unit in zip(AXES, ("d_11", "d_22", "d_66"), units, strict=True):
        d = samples[coef]
        row = {"name": coef, "unit": unit, "low": float(d.min()), "high": float(d.max())}
        if f"true_{force}" in samples:
            err = samples[force] - samples[f"true_{force}"]
            row["rel_error"] = float(np.linalg.norm(err) / np.linalg.norm(samples[f"true_{force}"]))
        row["over"] = f"{speed} {samples[speed].min():.3g} to {samples[speed].max():.3g}"
        rows.append(row)
    return rows


__all__ = ["AXES", "MASSES", "coefficient_rows", "covered_relative_velocities", "damping_samples"]
