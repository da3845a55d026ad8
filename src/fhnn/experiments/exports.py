"""What ``fhnn inspect`` writes for other tools: the learned coefficients over the covered region
as ``coefficients.csv`` and the learned flow on a grid as ``flow.nc``.

- ``coefficients.csv``: one row per point of a regular ``(r, σ)`` grid over the ranges the
  training data visit, kept where a visited pair lies near (within 5 % of each range, in the
  model's own flow, σ as :func:`~fhnn.evaluation.recovery.visited_r_sigma`); columns ``r, sigma``
  [m, m/s] then ``m_ax, m_ay, c_q, c_l`` [kg, kg, –, kg/s] and ``drag``, the total drag
  coefficient ``½ρA c_q σ + c_l`` [N·s/m] at that σ: what the data determine even where they
  cannot split it between ``c_q`` and ``c_l``.
- ``flow.nc``: NetCDF-4 (through xarray, h5netcdf engine) with coordinates ``x``, ``y`` [m] over
  the training positions' bounding box (and ``t`` over the training window for a time-dependent
  flow, on the clock of the table the data were imported from: its seconds, or "seconds since"
  its first date-time, which xarray reads as date-times) and variables ``u``, ``v`` [m/s] and
  ``psi`` [m²/s] of dims ``(y, x)`` or ``(t, y, x)``; points farther than ``reach`` from every
  training position (where the data say nothing about the flow) are NaN.

For an ensemble (``fhnn train --seeds N``) every value is the members' median at that point,
and ``NAME_lo``, ``NAME_hi`` columns (CSV) or ``u_lo``, ``u_hi``, … variables (NetCDF) hold the
ends of its 90 % interval (:func:`fhnn.training.ensemble.interval`); the grid is the first
member's. Both files are written atomically.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from fhnn.data.clock import dataset_clock
from fhnn.data.dataset import Dataset
from fhnn.data.table import write_table
from fhnn.evaluation.recovery import (
    RATIO_NAMES,
    coefficients_at,
    drag_ratios,
    drag_terms,
    flow_box,
    visited_r_sigma,
    window_times,
)
from fhnn.files import atomic_output
from fhnn.physics.body import COEFFICIENT_NAMES
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow
from fhnn.training.ensemble import interval


def coefficient_points(eom: EquationsOfMotion, dataset: Dataset, *, n: int = 40) -> np.ndarray:
    """The ``(r, σ)`` points ``(P, 2)`` [m, m/s] of an ``n × n`` grid over the region the training
    data cover in ``eom``'s flow, kept within 5 % of each range from a visited pair."""
    visited = visited_r_sigma(eom, dataset)
    lo, hi = visited.min(axis=0), visited.max(axis=0)
    span = np.maximum(hi - lo, 1e-12)
    rr, ss = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    grid = np.column_stack([rr.ravel(), ss.ravel()])
    dist, _ = cKDTree(visited / span).query(grid / span)
    return grid[dist <= 0.05]


def coefficient_grid(
    eoms: EquationsOfMotion | list[EquationsOfMotion], dataset: Dataset, *, n: int = 40
) -> dict[str, np.ndarray]:
    """The learned coefficients over :func:`coefficient_points` (of the first model) as columns
    ``r, sigma`` and :data:`GRID_NAMES` (the coefficients and the total drag); for several models
    (an ensemble) their median, with ``NAME_lo, NAME_hi`` after each ``NAME``."""
    members = eoms if isinstance(eoms, list) else [eoms]
    grid = coefficient_points(members[0], dataset, n=n)
    values = with_drag(member_coefficients(members, grid), grid, dataset)
    columns = {"r": grid[:, 0], "sigma": grid[:, 1]}
    if len(members) == 1:
        return {**columns, **{k: values[0, :, i] for i, k in enumerate(GRID_NAMES)}}
    median, lo, hi = interval(values)
    for i, k in enumerate(GRID_NAMES):
        columns.update({k: median[:, i], f"{k}_lo": lo[:, i], f"{k}_hi": hi[:, i]})
    return columns


#: The values ``coefficients.csv`` holds per ``(r, σ)``: the coefficients, then the total drag.
GRID_NAMES = (*COEFFICIENT_NAMES, "drag")


def member_coefficients(eoms: list[EquationsOfMotion], points: np.ndarray) -> np.ndarray:
    """Each model's coefficients at ``points`` ``(P, 2)``: shape ``(members, P, 4)``."""
    return np.stack([np.asarray(coefficients_at(e.coefficients, jnp.asarray(points))) for e in eoms])


def with_drag(values: np.ndarray, points: np.ndarray, dataset: Dataset) -> np.ndarray:
    """``values`` ``(members, P, 4)`` (coefficients at ``points`` ``(P, 2)``) with the total drag
    coefficient ``½ρA c_q σ + c_l`` [N·s/m] appended: shape ``(members, P, 5)``."""
    body = dataset.constants()
    drag = np.stack([drag_terms(v, points[:, 1], body)[1] for v in values])
    return np.concatenate([values, drag[..., None]], axis=-1)


def ensemble_intervals(
    eoms: list[EquationsOfMotion], dataset: Dataset, truth: EquationsOfMotion | None = None
) -> dict[str, dict[str, float]]:
    """Per coefficient, for the total drag coefficient (``drag``: ``½ρA c_q σ + c_l``) and per
    identifiable ratio (:data:`~fhnn.evaluation.recovery.RATIO_NAMES`), over
    :func:`coefficient_points`: the median over the points of the members' median
    (``median``), of the interval's ends (``lo``, ``hi``) and of its relative width
    ``(hi − lo) / |median|`` (``rel_width``). With ``truth`` also the true median (``true``),
    the fraction of points whose true value lies inside the interval (``coverage``) and the mean
    and max relative error of the members' median (``mean_rel``, ``max_rel``)."""
    grid = coefficient_points(eoms[0], dataset)
    body = dataset.constants()
    values = member_coefficients(eoms, grid)
    ratios = np.stack([drag_ratios(v, grid[:, 1], body) for v in values])
    exact = None if truth is None else member_coefficients([truth], grid)[0]
    out: dict[str, dict[str, float]] = {}
    for names, vals, true in (
        (
            GRID_NAMES,
            with_drag(values, grid, dataset),
            None if exact is None else with_drag(exact[None], grid, dataset)[0],
        ),
        (RATIO_NAMES, ratios, None if exact is None else drag_ratios(exact, grid[:, 1], body)),
    ):
        median, lo, hi = interval(vals)
        for i, name in enumerate(names):
            m = median[:, i]
            row = {
                "median": float(np.median(m)),
                "lo": float(np.median(lo[:, i])),
                "hi": float(np.median(hi[:, i])),
                "rel_width": float(np.median((hi[:, i] - lo[:, i]) / np.maximum(np.abs(m), 1e-300))),
            }
            if true is not None:
                t = true[:, i]
                rel = np.abs(m - t) / np.maximum(np.abs(t), 1e-300)
                inside = (lo[:, i] <= t) & (t <= hi[:, i])
                row.update(
                    true=float(np.median(t)),
                    coverage=float(np.mean(inside)),
                    mean_rel=float(np.mean(rel)),
                    max_rel=float(np.max(rel)),
                )
            out[name] = row
    return out


def write_coefficients_csv(
    eoms: EquationsOfMotion | list[EquationsOfMotion], dataset: Dataset, path: str | os.PathLike[str]
) -> Path:
    """Write :func:`coefficient_grid` to ``path`` (``.csv``)."""
    return write_table(coefficient_grid(eoms, dataset), path)


def write_flow_netcdf(
    flows: AbstractFlow | list[AbstractFlow],
    dataset: Dataset,
    path: str | os.PathLike[str],
    *,
    n: int = 60,
    n_times: int = 16,
    reach: float = 0.25,
) -> Path:
    """Write :func:`flow_dataset` to ``path`` (``.nc``, NetCDF-4) atomically; returns ``path``."""
    ds = flow_dataset(flows, dataset, n=n, n_times=n_times, reach=reach)
    path = Path(path)
    with atomic_output(path) as tmp:
        ds.to_netcdf(tmp, engine="h5netcdf")
    return path


def flow_dataset(
    flows: AbstractFlow | list[AbstractFlow],
    dataset: Dataset,
    *,
    n: int = 60,
    n_times: int = 16,
    reach: float = 0.25,
) -> Any:
    """The learned flow (of several models, an ensemble: the median and the interval) on an
    ``n × n`` grid over the training positions, as an ``xarray.Dataset`` (see the module
    docstring for its variables, units and NaN points)."""
    import xarray as xr

    x, y, near = flow_box(dataset, n=n, reach=reach)
    gx, gy = np.meshgrid(x, y)  # (y, x)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    members = flows if isinstance(flows, list) else [flows]
    steady = not members[0].time_dependent
    times = np.zeros(1) if steady else window_times(dataset, n_times)

    @eqx.filter_jit
    def fields(f: AbstractFlow, xy: jax.Array, ts: jax.Array) -> tuple[jax.Array, jax.Array]:
        at_time = lambda tt: (  # noqa: E731
            jax.vmap(lambda p: f.velocity(p, tt))(xy),
            jax.vmap(lambda p: f.stream(p, tt))(xy),
        )
        return jax.vmap(at_time)(ts)

    per_member = []
    for flow in members:
        vel, psi = (np.array(a) for a in fields(flow, jnp.asarray(points), jnp.asarray(times)))
        per_member.append(np.concatenate([vel, psi[..., None]], axis=-1).reshape(times.size, n, n, 3))
    stacked = np.stack(per_member)  # (members, t, y, x, 3): u, v, psi
    stacked[:, :, ~near] = np.nan
    dims = ("t", "y", "x")
    described = {
        "u": ("m s-1", "learned flow velocity, x component"),
        "v": ("m s-1", "learned flow velocity, y component"),
        "psi": ("m2 s-1", "learned stream function"),
    }
    data = {}
    if len(members) == 1:
        for i, (name, (units, long_name)) in enumerate(described.items()):
            data[name] = (dims, stacked[0, ..., i], {"units": units, "long_name": long_name})
    else:
        median, lo, hi = interval(stacked)
        for i, (name, (units, long_name)) in enumerate(described.items()):
            data[name] = (
                dims,
                median[..., i],
                {"units": units, "long_name": f"{long_name}, ensemble median"},
            )
            for end, values, which in (("lo", lo, "lower"), ("hi", hi, "upper")):
                data[f"{name}_{end}"] = (
                    dims,
                    values[..., i],
                    {"units": units, "long_name": f"{long_name}, {which} end of the 90 % interval"},
                )
    clock = dataset_clock(dataset)
    origin = clock["origin"]
    ds = xr.Dataset(
        data,
        coords={
            "t": (
                "t",
                times + clock["offset"],
                {"units": "s" if origin is None else f"seconds since {origin}"},
            ),
            "x": ("x", x, {"units": "m"}),
            "y": ("y", y, {"units": "m"}),
        },
        attrs={
            "title": "flow learned by fhnn",
            "note": f"NaN farther than {reach:g} m from every training position",
            "members": len(members),
        },
    )
    if steady:
        ds = ds.isel(t=0, drop=True)
    return ds


__all__ = [
    "GRID_NAMES",
    "coefficient_grid",
    "coefficient_points",
    "ensemble_intervals",
    "flow_dataset",
    "member_coefficients",
    "with_drag",
    "write_coefficients_csv",
    "write_flow_netcdf",
]
