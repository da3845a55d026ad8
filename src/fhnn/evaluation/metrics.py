"""Trajectory error metrics at horizons (docs/spec.md §5).

For a horizon ``H`` [s] the checkpoints are ``t = 1, 2, …, H`` (or ``0, 1, …, H`` with
``include_zero=True``, the paper's averaging, where ``t = 0`` contributes zero error). With
``Δx`` the position error and ``Δv`` the velocity error at a checkpoint:

- ``rmse_pos = sqrt(mean Δx²)`` over trajectories, checkpoints and both coordinates (``rmse_vel``
  likewise); ``mse_pos``, ``mse_vel`` are the squares;
- ``ade = mean ‖Δx‖`` over trajectories and checkpoints;
- ``fde = mean ‖Δx(H)‖`` over trajectories;
- ``within_eps`` = fraction of trajectories with ``‖Δx(H)‖ < eps`` (``eps = 0.01 m``);
- ``skill``: the Liu–Weisberg skill score drifter forecasters use (Liu & Weisberg 2011, J.
  Geophys. Res. 116, C09013), per trajectory ``1 − Σᵢ ‖Δxᵢ‖ / Σᵢ ℓᵢ`` clipped at 0, with ``ℓᵢ`` the
  length of the true path from the start to checkpoint ``i`` (over every sample), averaged over
  trajectories: 1 is a perfect forecast, 0 one whose separations add up to the distance travelled.

A diverged trajectory (non-finite prediction anywhere up to ``H``) is counted in ``diverged`` and
has an infinite error: no trajectory is left out, so ``mse_*``, ``rmse_*``, ``ade`` and ``fde`` are
``inf`` as soon as one trajectory diverged, and ``within_eps`` counts it as a failure.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fhnn.data.dataset import samples_until
from fhnn.errors import ConfigError


def checkpoint_indices(t: np.ndarray, horizon: float, *, include_zero: bool = False) -> np.ndarray:
    """Indices into the sample times ``t`` of the checkpoints ``(0,) 1, 2, …, H`` [s]."""
    if horizon <= 0 or not float(horizon).is_integer():
        raise ConfigError(f"horizon must be a positive whole number of seconds, got {horizon!r}")
    if horizon > t[-1] + 1e-9:
        raise ConfigError(f"horizon {horizon:g} s exceeds the trajectories' length {t[-1]:g} s")
    marks = np.arange(0 if include_zero else 1, int(horizon) + 1, dtype=float)
    idx = np.searchsorted(t, marks - 1e-9)
    if np.any(np.abs(t[np.minimum(idx, t.size - 1)] - marks) > 1e-9):
        raise ConfigError("the sample times do not contain every whole second up to the horizon")
    return idx


def trajectory_metrics(
    pred: np.ndarray,
    truth: np.ndarray,
    t: np.ndarray,
    horizon: float,
    *,
    eps: float = 0.01,
    include_zero: bool = False,
) -> dict[str, float]:
    """Metrics at ``horizon`` for predicted and true states of shape ``(N, T, 4)`` at times ``t``."""
    if pred.shape != truth.shape or pred.ndim != 3 or pred.shape[-1] != 4:
        raise ConfigError(
            f"pred and truth must both have shape (N, T, 4), got {pred.shape} and {truth.shape}"
        )
    idx = checkpoint_indices(t, horizon, include_zero=include_zero)
    upto = samples_until(t, horizon)
    finite = np.all(np.isfinite(pred[:, :upto]), axis=(1, 2))
    n = pred.shape[0]
    err = pred[:, idx] - truth[:, idx]
    err[~finite] = np.inf  # a diverged trajectory's error is infinite at every checkpoint
    path = path_length(truth[..., :2])[:, idx]
    skill = [liu_weisberg(np.linalg.norm(e[:, :2], axis=-1), p) for e, p in zip(err, path, strict=True)]
    return _scores(err, err[:, -1], int(n - finite.sum()), eps, skill)


def path_length(pos: np.ndarray) -> np.ndarray:
    """Length of the path through the positions ``pos`` ``(..., T, 2)`` from its first sample to
    each sample, shape ``(..., T)`` [m]."""
    steps = np.linalg.norm(np.diff(pos, axis=-2), axis=-1)
    return np.concatenate([np.zeros((*steps.shape[:-1], 1)), np.cumsum(steps, axis=-1)], axis=-1)


def liu_weisberg(separation: np.ndarray, path: np.ndarray) -> float:
    """The Liu–Weisberg skill ``max(0, 1 − Σ separation / Σ path)`` of one forecast, from its
    separations from the truth ``(K,)`` [m] and the true path's lengths ``(K,)`` [m] at the same
    checkpoints (tolerance n = 1). A body that has not moved scores 1 if the forecast stays on it."""
    total, travelled = float(np.sum(separation)), float(np.sum(path))
    if travelled == 0.0:
        return 1.0 if total == 0.0 else 0.0
    return max(0.0, 1.0 - total / travelled) if np.isfinite(total) else 0.0


@dataclass(frozen=True)
class Errors:
    """What a metric is computed from.

    Attributes:
        err: state errors at every checkpoint, pooled over trajectories, ``(..., 4)``.
        final: each trajectory's error at its last checkpoint, ``(N, 4)``.
        skill: each trajectory's Liu–Weisberg skill, ``(N,)``.
        diverged: trajectories whose rollout diverged.
        eps: the ``within_eps`` radius [m].
    """

    err: np.ndarray
    final: np.ndarray
    skill: list[float]
    diverged: int
    eps: float

    @property
    def final_distance(self) -> np.ndarray:
        """``‖Δx(H)‖`` per trajectory, ``(N,)`` [m]."""
        return np.linalg.norm(self.final[:, :2], axis=-1)


@dataclass(frozen=True)
class Metric:
    """A metric of rollouts at a horizon, as every report shows it.

    Attributes:
        name: its key in results (``fhnn evaluate --json``).
        label: its name in tables and figures, with the unit.
        header: its column header in ``fhnn evaluate`` (``""``: not shown there).
        format: how ``fhnn evaluate`` formats a value (``str.format``).
        compute: its value from :class:`Errors` (``None``: computed elsewhere, e.g.
            ``outside_training`` by :func:`fhnn.evaluation.evaluate.evaluate`).
        error: a diverged rollout makes it infinite (it counts in the divergence rule).
        fraction: a fraction in [0, 1] (tables show it in percent; figures on a linear axis).
        curve: a panel of the error-against-horizon figure.
    """

    name: str
    label: str
    header: str = ""
    format: str = "{:.3g}"
    compute: Callable[[Errors], float] | None = None
    error: bool = False
    fraction: bool = False
    curve: bool = False


#: Every metric, by name, in the order results hold them.
METRICS: dict[str, Metric] = {}


def register_metric(metric: Metric) -> Metric:
    """Add ``metric`` to :data:`METRICS` (after those already there); returns it."""
    METRICS[metric.name] = metric
    return metric


def _mse(err: np.ndarray, part: slice) -> float:
    return float(np.mean(err[..., part] ** 2))


for _metric in (
    Metric("mse_pos", "MSE(pos) [m²]", compute=lambda e: _mse(e.err, slice(0, 2)), error=True),
    Metric(
        "rmse_pos",
        "RMSE(pos) [m]",
        "RMSE\npos [m]",
        compute=lambda e: float(np.sqrt(_mse(e.err, slice(0, 2)))),
        error=True,
        curve=True,
    ),
    Metric("mse_vel", "MSE(vel) [m²/s²]", compute=lambda e: _mse(e.err, slice(2, 4)), error=True),
    Metric(
        "rmse_vel",
        "RMSE(vel) [m/s]",
        "RMSE\nvel [m/s]",
        compute=lambda e: float(np.sqrt(_mse(e.err, slice(2, 4)))),
        error=True,
    ),
    Metric(
        "ade",
        "ADE(pos) [m]",
        "ADE\n[m]",
        compute=lambda e: float(np.mean(np.linalg.norm(e.err[..., :2], axis=-1))),
        error=True,
        curve=True,
    ),
    Metric(
        "fde",
        "FDE(pos) [m]",
        "FDE\n[m]",
        compute=lambda e: float(np.mean(e.final_distance)),
        error=True,
        curve=True,
    ),
    Metric(
        "within_eps",
        "within 1 cm",
        "within\n1 cm",
        "{:.0%}",
        compute=lambda e: float(np.mean(e.final_distance < e.eps)),
        fraction=True,
        curve=True,
    ),
    Metric("skill", "Liu–Weisberg skill", "LW\nskill", "{:.2f}", compute=lambda e: float(np.mean(e.skill))),
    Metric("diverged", "diverged rollouts", "diverged", "{:d}", compute=lambda e: e.diverged),
    Metric("n_traj", "trajectories", compute=lambda e: int(e.final.shape[0])),
    Metric("outside_training", "left training region", "left\ntraining", "{:.0%}", fraction=True),
):
    register_metric(_metric)


def _scores(
    err: np.ndarray, final: np.ndarray, diverged: int, eps: float, skill: list[float]
) -> dict[str, float]:
    """Every computed metric of :data:`METRICS` from the state errors ``err`` ``(..., 4)`` at
    every checkpoint (pooled), ``final`` ``(N, 4)`` at each trajectory's last one, and each
    trajectory's ``skill``."""
    errors = Errors(err, final, skill, diverged, eps)
    return {m.name: m.compute(errors) for m in METRICS.values() if m.compute is not None}


def irregular_metrics(
    pred: np.ndarray,
    truth: np.ndarray,
    t: np.ndarray,
    mask: np.ndarray,
    horizon: float,
    *,
    eps: float = 0.01,
) -> dict[str, float]:
    """Metrics at ``horizon`` [s] for trajectories sampled at their own times ``t`` ``(N, T)``,
    real where ``mask`` ``(N, T)``: the checkpoints of a trajectory are its samples in ``(t₀,
    t₀ + H]``, ``fde`` is the error at the last of them. Only trajectories that last at least
    ``H`` (to half their median step) are scored; ``n_traj`` says how many. Diverged trajectories
    count as for :func:`trajectory_metrics`."""
    if horizon <= 0:
        raise ConfigError(f"horizon must be > 0 s, got {horizon!r}")
    rel = t - t[:, :1]
    counts = mask.sum(axis=1)
    end = rel[np.arange(rel.shape[0]), counts - 1]
    step = np.median(np.diff(rel, axis=1)[mask[:, 1:]])
    scored = np.flatnonzero(end >= horizon - 0.5 * step)
    if scored.size == 0:
        raise ConfigError(
            f"horizon {horizon:g} s exceeds every trajectory's length (longest {end.max():g} s)"
        )
    errors, skill, diverged = [], [], 0
    for i in scored:
        upto = mask[i] & (rel[i] <= horizon + 1e-9)
        keep = upto & (rel[i] > 0)
        err = pred[i, keep] - truth[i, keep]
        if not np.all(np.isfinite(pred[i, upto])):
            diverged += 1
            err = np.full_like(err, np.inf)
        errors.append(err)
        path = path_length(truth[i, upto, :2])[keep[upto]]
        skill.append(liu_weisberg(np.linalg.norm(err[:, :2], axis=-1), path))
    return _scores(np.concatenate(errors), np.stack([e[-1] for e in errors]), diverged, eps, skill)
