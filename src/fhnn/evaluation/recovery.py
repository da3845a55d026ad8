"""Parameter and flow recovery (docs/spec.md §5, beyond the paper).

- Coefficients: the learned ``(m_ax, m_ay, c_q, c_l)(r, σ)`` against the true laws at the
  ``(r, σ)`` pairs the training data visits; per coefficient the mean and the maximum relative
  error over those pairs; and the same per band of σ (quantile bands of the visited σ), with the
  share ``½ρA c_q σ / (½ρA c_q σ + c_l)`` of the quadratic term in the true drag there — where
  that share is small the data constrain ``c_q`` only weakly (the drag force is
  ``−(½ρA c_q σ + c_l) v_rel``, so ``c_q`` at small σ is a small correction to ``c_l``).
- Flow: relative L2 error ``‖u_θ − u‖ / ‖u‖`` over the grid points (within the bounding box of
  the training positions) that lie within ``reach`` of a training position and in the fluid (not
  inside a solid body such as the obstacle's cylinder).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy.spatial import cKDTree

from fhnn.data.dataset import Dataset
from fhnn.data.summary import relative_speeds
from fhnn.physics.body import COEFFICIENT_NAMES, AbstractCoefficients
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow, velocity_field


def visited_r_sigma(eom: EquationsOfMotion, dataset: Dataset, *, max_points: int = 20000) -> np.ndarray:
    """``(r, σ)`` pairs [m, m/s] at the clean training states (subsampled), shape ``(P, 2)``, r
    and σ as ``eom`` sees them (the truth's, or a model's where the truth is unknown)."""
    split = dataset.train
    states = split.states_clean[split.mask]
    ts = split.times[split.mask]
    if states.shape[0] > max_points:
        idx = np.random.default_rng(0).choice(states.shape[0], max_points, replace=False)
        states, ts = states[idx], ts[idx]
    sigma = relative_speeds(eom, states, ts)
    return np.column_stack([np.asarray(eom.radius(states[:, :2])), sigma])


@eqx.filter_jit
def coefficients_at(coefficients: AbstractCoefficients, points: jax.Array) -> jax.Array:
    """``coefficients`` at the ``(r, σ)`` points ``(P, 2)`` [m, m/s], shape ``(P, 4)``."""
    return jax.vmap(coefficients)(points[:, 0], points[:, 1])


#: Quantiles of the visited σ that bound the bands of :func:`coefficient_recovery`'s ``_by_sigma``.
SIGMA_BANDS = (0.0, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)


#: The drag-to-inertia ratios that unforced motion determines: with no known force the
#: equations of motion fix only ``c / (M + m_a)`` (a common scale of inertia and drag leaves the
#: motion unchanged when the body is neutrally buoyant, ``ρV = M``). ``drag/(M+m_a)`` is the total
#: drag coefficient's ``(½ρA c_q σ + c_l) / (M + m_a)`` [1/s], the rate at which the relative
#: velocity relaxes at speed σ: what the motion itself shows, even where the data cannot split the
#: drag between ``c_q`` and ``c_l`` (the split rests on how the drag behaves as σ → 0).
RATIO_NAMES = (
    "c_l/(M+m_ax)",
    "c_l/(M+m_ay)",
    "c_q/(M+m_ax)",
    "c_q/(M+m_ay)",
    "drag/(M+m_ax)",
    "drag/(M+m_ay)",
)


def drag_ratios(coefficients: np.ndarray, sigma: np.ndarray, body: dict[str, float]) -> np.ndarray:
    """:data:`RATIO_NAMES` [1/s, 1/s, 1/kg, 1/kg, 1/s, 1/s] from coefficients ``(P, 4)`` (``m_ax,
    m_ay, c_q, c_l``) at the relative speeds ``sigma`` ``(P,)`` [m/s], for the body constants
    ``body`` (``M``, ``rho``, ``A``), shape ``(P, 6)``."""
    m_ax, m_ay, c_q, c_l = coefficients.T
    drag = drag_terms(coefficients, sigma, body)[1]
    inertia_x, inertia_y = body["M"] + m_ax, body["M"] + m_ay
    stack = jnp.stack if isinstance(coefficients, jax.Array) else np.stack
    return stack(
        [
            c_l / inertia_x,
            c_l / inertia_y,
            c_q / inertia_x,
            c_q / inertia_y,
            drag / inertia_x,
            drag / inertia_y,
        ],
        axis=1,
    )


def coefficient_recovery(learned: AbstractCoefficients, dataset: Dataset) -> dict[str, Any]:
    """Per coefficient: ``mean_rel``, ``max_rel`` error and the ranges of learned and true values;
    ``_coverage``: the (r, σ) ranges [m, m/s]; ``_drag``: the same errors and ranges of the total
    drag coefficient ``½ρA c_q σ + c_l`` [N·s/m] (the data determine it even where they cannot split
    it between ``c_q`` and ``c_l``); ``_by_sigma``: per σ band (quantiles :data:`SIGMA_BANDS` of
    the visited σ) its bounds [m/s], number of points, the true quadratic share of the drag, each
    coefficient's and (``drag``) the total drag's maximum relative error."""
    truth_eom = dataset.equations()
    points = visited_r_sigma(truth_eom, dataset)
    got = np.asarray(coefficients_at(learned, jnp.asarray(points)))
    want = np.asarray(coefficients_at(truth_eom.coefficients, jnp.asarray(points)))
    out: dict[str, Any] = {}
    rel_all = np.abs(got - want) / np.maximum(np.abs(want), 1e-12)
    for i, name in enumerate(COEFFICIENT_NAMES):
        rel = rel_all[:, i]
        out[name] = {
            "mean_rel": float(rel.mean()),
            "max_rel": float(rel.max()),
            "learned_min": float(got[:, i].min()),
            "learned_max": float(got[:, i].max()),
            "true_min": float(want[:, i].min()),
            "true_max": float(want[:, i].max()),
        }
    out["_coverage"] = _coverage(points)
    # the total drag coefficient, what the data pin down even where they cannot split it
    body = dataset.constants()
    drag_got, drag_want = (drag_terms(c, points[:, 1], body)[1] for c in (got, want))
    rel_drag = np.abs(drag_got - drag_want) / np.maximum(np.abs(drag_want), 1e-12)
    out["_drag"] = {
        "mean_rel": float(rel_drag.mean()),
        "max_rel": float(rel_drag.max()),
        "learned_min": float(drag_got.min()),
        "learned_max": float(drag_got.max()),
        "true_min": float(drag_want.min()),
        "true_max": float(drag_want.max()),
    }
    out["_by_sigma"] = _by_sigma(
        points, want, dataset, lambda inside: rel_all[inside].max(axis=0), extra={"drag": rel_drag}
    )
    got_r, want_r = (drag_ratios(c, points[:, 1], body) for c in (got, want))
    rel_r = np.abs(got_r - want_r) / np.maximum(np.abs(want_r), 1e-300)
    out["_ratios"] = {
        name: {"mean_rel": float(rel_r[:, i].mean()), "max_rel": float(rel_r[:, i].max())}
        for i, name in enumerate(RATIO_NAMES)
    }
    return out


#: What :func:`coefficient_medians` returns, in order: the coefficients, the total drag
#: coefficient and the ratios.
SUMMARY_NAMES = (*COEFFICIENT_NAMES, "drag", *RATIO_NAMES)


def coefficient_medians(
    coefficients: AbstractCoefficients, points: jax.Array, body: dict[str, float]
) -> jax.Array:
    """The median of each of :data:`SUMMARY_NAMES` over the ``(r, σ)`` points ``(P, 2)`` [m, m/s]
    for the body constants ``body``, shape ``(11,)`` [kg, kg, 1, N·s/m, N·s/m, then the ratios'
    units]. Traceable: a function JAX differentiates in the coefficients' parameters."""
    got = jax.vmap(coefficients)(points[:, 0], points[:, 1])
    drag = drag_terms(got, points[:, 1], body)[1]
    table = jnp.concatenate([got, drag[:, None], drag_ratios(got, points[:, 1], body)], axis=1)
    return jnp.median(table, axis=0)


def drag_terms(
    coefficients: np.ndarray, sigma: np.ndarray, body: dict[str, float]
) -> tuple[np.ndarray, np.ndarray]:
    """The quadratic term ``½ρA c_q σ`` and the total drag coefficient ``½ρA c_q σ + c_l``
    [N·s/m] of ``coefficients`` ``(P, 4)`` at the relative speeds ``sigma`` ``(P,)`` [m/s], for the
    body constants ``body`` (``rho``, ``A``)."""
    quad = 0.5 * body["rho"] * body["A"] * coefficients[:, 2] * sigma
    return quad, quad + coefficients[:, 3]


def _coverage(points: np.ndarray) -> dict[str, float]:
    """The ranges of the visited ``(r, σ)`` points ``(P, 2)`` [m, m/s]."""
    return {
        "r_min": float(points[:, 0].min()),
        "r_max": float(points[:, 0].max()),
        "sigma_min": float(points[:, 1].min()),
        "sigma_max": float(points[:, 1].max()),
    }


def _by_sigma(
    points: np.ndarray,
    coefficients: np.ndarray,
    dataset: Dataset,
    per_band: Callable[[np.ndarray], np.ndarray],
    extra: dict[str, np.ndarray] | None = None,
) -> list[dict[str, Any]]:
    """Per band of σ (quantiles :data:`SIGMA_BANDS` of the visited σ): its bounds [m/s], number of
    points, the share ``½ρA c_q σ / (½ρA c_q σ + c_l)`` of the quadratic term in the drag of
    ``coefficients`` ``(P, 4)`` there, ``per_band(inside)`` (one value per coefficient) for
    the points ``inside`` it, and for each ``extra`` name its per-point values' maximum there."""
    sigma = points[:, 1]
    quad, drag = drag_terms(coefficients, sigma, dataset.constants())
    share = quad / np.maximum(drag, 1e-300)
    edges = np.quantile(sigma, SIGMA_BANDS)
    band = np.clip(np.searchsorted(edges, sigma, side="right") - 1, 0, len(edges) - 2)
    out = []
    for b in range(len(edges) - 1):
        inside = band == b
        if not inside.any():
            continue
        out.append(
            {
                "sigma_lo": float(edges[b]),
                "sigma_hi": float(edges[b + 1]),
                "points": int(inside.sum()),
                "quadratic_share": float(share[inside].mean()),
                **dict(zip(COEFFICIENT_NAMES, np.asarray(per_band(inside)).tolist(), strict=True)),
                **{name: float(values[inside].max()) for name, values in (extra or {}).items()},
            }
        )
    return out


def learned_coefficients(learned: EquationsOfMotion, dataset: Dataset) -> dict[str, Any]:
    """The coefficients of a learned model where no truth is known (imported data): per
    coefficient, and for the total drag coefficient ``drag`` = ``½ρA c_q σ + c_l`` [N·s/m], the
    median and the range over the ``(r, σ)`` the training data visit (σ in the learned flow);
    ``_coverage`` as for :func:`coefficient_recovery`; ``_by_sigma``: per σ band its bounds,
    points, the learned quadratic share of the drag and each coefficient's median."""
    points = visited_r_sigma(learned, dataset)
    got = np.asarray(coefficients_at(learned.coefficients, jnp.asarray(points)))
    drag = drag_terms(got, points[:, 1], dataset.constants())[1]
    out: dict[str, Any] = {
        name: {
            "median": float(np.median(values)),
            "learned_min": float(values.min()),
            "learned_max": float(values.max()),
        }
        for name, values in (*zip(COEFFICIENT_NAMES, got.T, strict=True), ("drag", drag))
    }
    out["_coverage"] = _coverage(points)
    out["_by_sigma"] = _by_sigma(points, got, dataset, lambda inside: np.median(got[inside], axis=0))
    ratios = drag_ratios(got, points[:, 1], dataset.constants())
    out["_ratios"] = {
        name: {
            "median": float(np.median(ratios[:, i])),
            "learned_min": float(ratios[:, i].min()),
            "learned_max": float(ratios[:, i].max()),
        }
        for i, name in enumerate(RATIO_NAMES)
    }
    return out


def flow_box(
    dataset: Dataset, *, n: int = 60, reach: float = 0.25
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An ``n × n`` grid over the training positions' bounding box: ``x`` ``(n,)``, ``y`` ``(n,)``
    [m] and ``near`` ``(n, n)`` (indexed ``[y, x]``), true within ``reach`` m of a sample and, for
    simulated data, in the fluid (:meth:`AbstractFlow.in_fluid`: not inside the obstacle's
    cylinder, which ``reach`` crosses where trajectories pass close to it)."""
    pos = dataset.train.states_clean[dataset.train.mask][:, :2]
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    x, y = np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)
    gx, gy = np.meshgrid(x, y)
    points = np.column_stack([gx.ravel(), gy.ravel()])
    dist, _ = cKDTree(pos).query(points)
    near = dist <= reach
    if not dataset.imported:
        near &= dataset.scenario_object().flow().in_fluid(points)
    return x, y, near.reshape(n, n)


def flow_grid(dataset: Dataset, *, n: int = 60, reach: float = 0.25) -> np.ndarray:
    """Grid points ``(P, 2)`` in the training data's bounding box within ``reach`` m of a sample
    and in the fluid (see :func:`flow_box`)."""
    x, y, near = flow_box(dataset, n=n, reach=reach)
    gx, gy = np.meshgrid(x, y)
    return np.column_stack([gx.ravel(), gy.ravel()])[near.ravel()]


def window_times(dataset: Dataset, n_times: int = 16) -> np.ndarray:
    """``n_times`` evenly spaced times [s] over the training trajectories' time window."""
    times = dataset.train.times[dataset.train.mask]
    return np.linspace(float(times.min()), float(times.max()), n_times)


def flow_recovery(
    learned: AbstractFlow, dataset: Dataset, *, t: float | None = None, n_times: int = 16
) -> dict[str, Any]:
    """Relative L2 error of the learned flow velocity on :func:`flow_grid`, pooled over times.

    At the time ``t`` [s] when given; else, for a time-dependent true flow, at ``n_times`` evenly
    spaced times over the training trajectories' time window (a flow frozen at one instant, or
    right at one phase of a wave, does not score well), and at ``t = 0`` for a steady one.
    Returns ``rel_l2`` (``‖u_θ − u‖ / ‖u‖`` over every point and time), ``points`` (grid points)
    and ``times`` [s].
    """
    truth = dataset.scenario_object().flow()
    if t is not None:
        times = np.asarray([float(t)])
    elif truth.time_dependent:
        times = window_times(dataset, n_times)
    else:
        times = np.zeros(1)
    grid = jnp.asarray(flow_grid(dataset))
    u_hat = np.asarray(velocity_field(learned, grid, jnp.asarray(times)))
    u = np.asarray(velocity_field(truth, grid, jnp.asarray(times)))
    return {
        "rel_l2": float(np.linalg.norm(u_hat - u) / max(np.linalg.norm(u), 1e-300)),
        "points": int(grid.shape[0]),
        "times": times.tolist(),
    }
