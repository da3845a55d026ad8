"""Evaluating a model of a body that turns against the simulator's truth or a table's observations.

- Forecasts: each test trajectory from its first state (as trained on) under its known forcing,
  integrated with adaptive Dopri8 (rtol = atol = 1e-10); ``rmse_pos`` [m] over trajectories, both
  coordinates and the checkpoints ``1, 2, …, H`` s after each trajectory's start (the sample
  nearest each: exact on a simulation's grid), against the reference states (a simulation's
  truth, an import's observations); ``rmse_heading`` [rad] likewise, differences wrapped into
  (−π, π]; a forecast that fails to finish counts as diverged and makes both infinite.
  An imported data set gets only these, with the learned added masses.
- Added masses: learned against true ``(m_11, m_22, m_66)``, relative errors.
- Damping: per axis, the relative L2 error of the learned ``D(ν_r) ν_r`` against the truth's over
  the relative velocities the training split visits (under the true flow), and the largest local
  error as a fraction of the largest true damping on that axis.
- Flow: relative L2 error of the learned velocity on a 60 × 60 grid over the training positions'
  bounding box, at points within 0.25 m of one, pooled over 16 times of the training window for a
  time-dependent flow (at t = 0 for a steady one).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from fhnn.data.planar import PlanarDataset, PlanarSplit, solve_planar
from fhnn.errors import ConfigError
from fhnn.models.planar import PlanarFHNN
from fhnn.physics.flows import velocity_field
from fhnn.physics.planar import PlanarEquations, water_at_body

Array = jax.Array
ROLLOUT_TOL = 1e-10
#: A forecast stops, as diverged, once any state entry exceeds this (model units: m, rad, m/s).
ROLLOUT_BOUND = 1e6


def checkpoints(split: PlanarSplit, horizon: float) -> np.ndarray:
    """Each trajectory's sample nearest ``1, 2, …, H`` s after its start, ``(N, H)`` indices.

    Raises:
        ConfigError: ``horizon`` is not a positive whole number of seconds, or a trajectory is
            shorter than it.
    """
    if not (horizon > 0 and float(horizon).is_integer()):
        raise ConfigError(f"horizon must be a positive whole number of seconds, got {horizon!r}")
    last = split.t[np.arange(split.t.shape[0]), split.lengths - 1] - split.t[:, 0]
    if np.min(last) < horizon - 1e-9:
        raise ConfigError(f"horizon {horizon:g} s exceeds the shortest test trajectory ({np.min(last):g} s)")
    marks = split.t[:, :1] + np.arange(1, int(horizon) + 1, dtype=float)[None, :]
    gap = np.abs(split.t[:, None, :] - marks[:, :, None])
    gap[~np.broadcast_to(split.valid()[:, None, :], gap.shape)] = np.inf
    return np.argmin(gap, axis=2)


def forecast(
    model: PlanarFHNN | PlanarEquations, split: PlanarSplit, horizon: float
) -> tuple[np.ndarray, np.ndarray]:
    """``model``'s forecasts of ``split`` from each trajectory's first state over its sample times
    up to the latest of :func:`checkpoints`: states ``(N, T_H, 6)`` and whether each finished,
    ``(N,)``."""
    upto = int(checkpoints(split, horizon).max()) + 1
    states, ok = solve_planar(
        model,
        jnp.asarray(split.states[:, 0]),
        jnp.asarray(split.thrust),
        jnp.asarray(split.t[:, :upto]),
        jnp.asarray(split.residual()[:, :upto]),
        tol=ROLLOUT_TOL,
        bound=ROLLOUT_BOUND,
    )
    return np.asarray(states), np.asarray(ok)


def forecast_errors(pred: np.ndarray, ok: np.ndarray, split: PlanarSplit, horizon: float) -> dict[str, float]:
    """``rmse_pos`` [m] and ``rmse_heading`` [rad] at :func:`checkpoints` up to ``horizon``
    against the split's reference states, and the count of ``diverged`` forecasts."""
    idx = checkpoints(split, horizon)
    rows = np.arange(idx.shape[0])[:, None]
    err = pred[rows, idx] - split.states_clean[rows, idx]
    finite = ok & np.all(np.isfinite(pred), axis=(1, 2))
    if not finite.all():
        return {"rmse_pos": float("inf"), "rmse_heading": float("inf"), "diverged": int((~finite).sum())}
    return {
        "rmse_pos": float(np.sqrt(np.mean(err[..., :2] ** 2))),
        "rmse_heading": float(np.sqrt(np.mean(np.angle(np.exp(1j * err[..., 2])) ** 2))),
        "diverged": 0,
    }


def relative_velocities(dataset: PlanarDataset, max_points: int = 20000) -> np.ndarray:
    """The relative velocities ``ν_r`` the training split visits under the true flow, ``(P, 3)``
    (an even subsample of at most ``max_points``)."""
    train = dataset.splits["train"]
    flow = dataset.truth().flow()
    states, times = train.states_clean[train.valid()], train.t[train.valid()]
    keep = np.linspace(0, states.shape[0] - 1, min(max_points, states.shape[0])).astype(int)
    s, tt = jnp.asarray(states[keep]), jnp.asarray(times[keep])
    nu_c = jax.vmap(lambda st, ti: water_at_body(flow, st[:3], ti))(s, tt)
    return np.asarray(s[:, 3:] - nu_c)


def damping_errors(model: PlanarFHNN, dataset: PlanarDataset) -> dict[str, Any]:
    """Per axis (surge, sway, yaw): ``rel_l2`` of the learned damping force against the truth's
    over :func:`relative_velocities`, and ``max_local`` (the largest error over the largest true
    damping on that axis)."""
    nu_r = jnp.asarray(relative_velocities(dataset))
    true = np.asarray(jax.vmap(dataset.truth().damping())(nu_r))
    learned = np.asarray(jax.vmap(model.damping)(nu_r))
    err = learned - true
    out: dict[str, Any] = {}
    for i, axis in enumerate(("surge", "sway", "yaw")):
        out[axis] = {
            "rel_l2": float(np.linalg.norm(err[:, i]) / np.linalg.norm(true[:, i])),
            "max_local": float(np.max(np.abs(err[:, i])) / np.max(np.abs(true[:, i]))),
        }
    out["points"] = int(nu_r.shape[0])
    return out


def flow_error(
    model: PlanarFHNN, dataset: PlanarDataset, *, n: int = 60, reach: float = 0.25, n_times: int = 16
) -> dict[str, Any]:
    """``rel_l2`` of the learned flow's velocity on the grid near the training positions (see the
    module's description), with the number of ``points`` and the ``times`` [s]."""
    train = dataset.splits["train"]
    pos = train.states_clean[train.valid()][:, :2]
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    dist, _ = cKDTree(pos).query(grid)
    grid = jnp.asarray(grid[dist <= reach])
    truth = dataset.truth().flow()
    span = train.t[train.valid()]
    times = np.linspace(span.min(), span.max(), n_times) if truth.time_dependent else np.zeros(1)
    u = np.asarray(velocity_field(truth, grid, jnp.asarray(times)))
    u_hat = np.asarray(velocity_field(model.flow, grid, jnp.asarray(times)))
    return {
        "rel_l2": float(np.linalg.norm(u_hat - u) / np.linalg.norm(u)),
        "points": int(grid.shape[0]),
        "times": times.tolist(),
    }


def evaluate_planar(model: PlanarFHNN, dataset: PlanarDataset, *, horizon: float = 5.0) -> dict[str, Any]:
    """Forecasts of the test split to ``horizon`` [s] (:func:`forecast_errors`) and, for a
    simulation, the added masses, the damping (:func:`damping_errors`) and the flow
    (:func:`flow_error`) against the truth; for an import, the learned added masses.

    Raises:
        ConfigError: ``horizon`` is not a positive whole number of seconds within every test
            trajectory.
    """
    pred, ok = forecast(model, dataset.splits["test"], horizon)
    learned = np.asarray(model.added_mass())
    report = {"horizon": horizon, "forecast": forecast_errors(pred, ok, dataset.splits["test"], horizon)}
    if not dataset.has_truth:
        masses = zip(("m_11", "m_22", "m_66"), learned, strict=True)
        return {**report, "added_mass": {k: {"learned": float(a)} for k, a in masses}}
    true = np.asarray(dataset.params["added_mass"], float)
    return {
        **report,
        "added_mass": {
            name: {"learned": float(a), "true": float(b), "rel_error": float(abs(a - b) / b)}
            for name, a, b in zip(("m_11", "m_22", "m_66"), learned, true, strict=True)
        },
        "damping": damping_errors(model, dataset),
        "flow": flow_error(model, dataset),
    }


__all__ = [
    "checkpoints",
    "damping_errors",
    "evaluate_planar",
    "flow_error",
    "forecast",
    "forecast_errors",
    "relative_velocities",
]
