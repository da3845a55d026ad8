"""What ``fhnn inspect`` writes for other tools: the learned coefficients over the covered region
as ``coefficients.csv`` and the learned flow on a grid as ``flow.nc``.

- ``coefficients.csv``: one row per point of a regular ``(r, σ)`` grid over the ranges the
  training data visit, kept where a visited pair lies near (within 5 % of each range, in the
  model's own flow, σ as :func:`~fhnn.evaluation.recovery.visited_r_sigma`); columns ``r, sigma``
  [m, m/s] then ``m_ax, m_ay, c_q, c_l`` [kg, kg, –, kg/s].
- ``flow.nc``: NetCDF-4 (through xarray, h5netcdf engine) with coordinates ``x``, ``y`` [m] over
  the training positions' bounding box (and ``t`` [s] over the training window for a
  time-dependent flow) and variables ``u``, ``v`` [m/s] and ``psi`` [m²/s] of dims ``(y, x)`` or
  ``(t, y, x)``; points farther than ``reach`` from every training position (where the data say
  nothing about the flow) are NaN.

Both are written atomically. Ensemble intervals (``NAME_lo``, ``NAME_hi``) need an ensemble,
which training does not make yet.
"""

from __future__ import annotations

import os
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from fhnn.data.dataset import Dataset
from fhnn.data.table import write_table
from fhnn.evaluation.recovery import coefficients_at, flow_box, visited_r_sigma, window_times
from fhnn.files import atomic_output
from fhnn.physics.body import COEFFICIENT_NAMES
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow


def coefficient_grid(eom: EquationsOfMotion, dataset: Dataset, *, n: int = 40) -> dict[str, np.ndarray]:
    """The learned coefficients on an ``n × n`` ``(r, σ)`` grid over the covered region (see the
    module docstring), as columns ``r, sigma, m_ax, m_ay, c_q, c_l``."""
    visited = visited_r_sigma(eom, dataset)
    lo, hi = visited.min(axis=0), visited.max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    rr, ss = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    grid = np.column_stack([rr.ravel(), ss.ravel()])
    dist, _ = cKDTree(visited / span).query(grid / span)
    grid = grid[dist <= 0.05]
    values = np.asarray(coefficients_at(eom.coefficients, jnp.asarray(grid)))
    return {
        "r": grid[:, 0],
        "sigma": grid[:, 1],
        **{k: values[:, i] for i, k in enumerate(COEFFICIENT_NAMES)},
    }


def write_coefficients_csv(eom: EquationsOfMotion, dataset: Dataset, path: str | os.PathLike[str]) -> Path:
    """Write :func:`coefficient_grid` to ``path`` (``.csv``)."""
    return write_table(coefficient_grid(eom, dataset), path)


def write_flow_netcdf(
    flow: AbstractFlow,
    dataset: Dataset,
    path: str | os.PathLike[str],
    *,
    n: int = 60,
    n_times: int = 16,
    reach: float = 0.25,
) -> Path:
    """Write the learned ``flow`` on an ``n × n`` grid over the training positions (see the module
    docstring) to ``path`` (``.nc``)."""
    import xarray as xr

    x, y, near = flow_box(dataset, n=n, reach=reach)
    gx, gy = np.meshgrid(x, y)  # (y, x)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    steady = not flow.time_dependent
    times = np.zeros(1) if steady else window_times(dataset, n_times)

    @eqx.filter_jit
    def fields(f: AbstractFlow, xy: jax.Array, ts: jax.Array) -> tuple[jax.Array, jax.Array]:
        at_time = lambda tt: (  # noqa: E731
            jax.vmap(lambda p: f.velocity(p, tt))(xy),
            jax.vmap(lambda p: f.stream(p, tt))(xy),
        )
        return jax.vmap(at_time)(ts)

    vel, psi = (np.array(a) for a in fields(flow, jnp.asarray(points), jnp.asarray(times)))
    vel = vel.reshape(times.size, n, n, 2)
    psi = psi.reshape(times.size, n, n)
    for a in (vel[..., 0], vel[..., 1], psi):
        a[:, ~near] = np.nan
    dims = ("t", "y", "x")
    data = {
        "u": (dims, vel[..., 0], {"units": "m s-1", "long_name": "learned flow velocity, x component"}),
        "v": (dims, vel[..., 1], {"units": "m s-1", "long_name": "learned flow velocity, y component"}),
        "psi": (dims, psi, {"units": "m2 s-1", "long_name": "learned stream function"}),
    }
    ds = xr.Dataset(
        data,
        coords={
            "t": ("t", times, {"units": "s"}),
            "x": ("x", x, {"units": "m"}),
            "y": ("y", y, {"units": "m"}),
        },
        attrs={
            "title": "flow learned by fhnn",
            "note": f"NaN farther than {reach:g} m from every training position",
        },
    )
    if steady:
        ds = ds.isel(t=0, drop=True)
    path = Path(path)
    with atomic_output(path) as tmp:
        ds.to_netcdf(tmp, engine="h5netcdf")
    return path


__all__ = ["coefficient_grid", "write_coefficients_csv", "write_flow_netcdf"]
