"""Figures: learned vs true flow (quiver and streamlines), coefficients, rollouts.

All functions draw with matplotlib's non-interactive Agg backend and write PNG (and SVG where
asked) files; they return the paths written.
"""

from __future__ import annotations

from pathlib import Path

import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.evaluation.metrics import METRICS
from fhnn.evaluation.recovery import coefficients_at, flow_recovery, visited_r_sigma
from fhnn.physics.body import COEFFICIENT_NAMES, AbstractCoefficients
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import AbstractFlow, velocity_field

UNITS = {"m_ax": "kg", "m_ay": "kg", "c_q": "-", "c_l": "N·s/m"}


def _save(fig: plt.Figure, path: Path, formats: tuple[str, ...]) -> list[Path]:
    written = []
    for ext in formats:
        target = path.with_suffix(f".{ext}")
        fig.savefig(target, dpi=130, bbox_inches="tight")
        written.append(target)
    plt.close(fig)
    return written


def _velocity_grid(flow: AbstractFlow, xs: np.ndarray, ys: np.ndarray, t: float) -> np.ndarray:
    gx, gy = np.meshgrid(xs, ys)
    pts = jnp.asarray(np.column_stack([gx.ravel(), gy.ravel()]))
    u = np.asarray(velocity_field(flow, pts, jnp.asarray([float(t)]))[0])
    return u.reshape(ys.size, xs.size, 2)


def _coverage_mask(pos: np.ndarray, xs: np.ndarray, ys: np.ndarray, reach: float) -> np.ndarray:
    """``(len(ys), len(xs))`` bools: grid points within ``reach`` m of a training position."""
    from scipy.spatial import cKDTree

    gx, gy = np.meshgrid(xs, ys)
    dist, _ = cKDTree(pos).query(np.column_stack([gx.ravel(), gy.ravel()]))
    return (dist <= reach).reshape(gx.shape)


def flow_figure(
    learned: AbstractFlow,
    truth: AbstractFlow | None,
    dataset: Dataset,
    path: Path,
    *,
    t: float = 0.0,
    formats: tuple[str, ...] = ("png",),
) -> list[Path]:
    """Three panels over the training region at time ``t``: the true and the learned flow (speed
    as colour on one shared scale, streamlines), and the error ``|u_θ − u|``; the outline marks
    where the training data lie (within 0.25 m of a training position), the only place where the
    learned flow is pinned by the samples rather than extrapolated. Without a truth (imported data): the
    learned flow alone."""
    pos = dataset.train.states_clean[dataset.train.mask][:, :2]
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    pad = 0.05 * (hi - lo)
    xs = np.linspace(lo[0] - pad[0], hi[0] + pad[0], 60)
    ys = np.linspace(lo[1] - pad[1], hi[1] + pad[1], 60)
    covered = _coverage_mask(pos, xs, ys, 0.25)
    learned_u = _velocity_grid(learned, xs, ys, t)
    if truth is None:
        fig, ax = plt.subplots(figsize=(7.5, 5.8), layout="constrained")
        speed = np.hypot(learned_u[..., 0], learned_u[..., 1])
        mesh = ax.pcolormesh(xs, ys, speed, cmap="viridis", shading="auto")
        ax.streamplot(xs, ys, learned_u[..., 0], learned_u[..., 1], color="white", linewidth=0.6, density=1.1)
        fig.colorbar(mesh, ax=ax, label="learned flow speed |u| [m/s]")
        ax.contour(xs, ys, covered.astype(float), levels=[0.5], colors="red", linewidths=1.2)
        ax.plot([], [], color="red", label="training data region")
        ax.legend(loc="upper right", fontsize=8, framealpha=0.8)
        ax.set(title=f"learned flow, t = {t:g} s", xlabel="x [m]", ylabel="y [m]", aspect="equal")
        return _save(fig, path, formats)
    true_u = _velocity_grid(truth, xs, ys, t)
    speeds = [np.hypot(u[..., 0], u[..., 1]) for u in (true_u, learned_u)]
    vmax = max(float(np.max(speeds[0][covered], initial=0.0)), float(np.max(speeds[1][covered], initial=0.0)))
    error = np.hypot(*(learned_u - true_u).transpose(2, 0, 1))
    rel = flow_recovery(learned, dataset, t=t)["rel_l2"]  # at this instant (inspect: over the window)
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2), layout="constrained")
    for ax, label, u, speed in zip(axes[:2], ("true", "learned"), (true_u, learned_u), speeds, strict=True):
        mesh = ax.pcolormesh(xs, ys, speed, cmap="viridis", vmin=0.0, vmax=vmax, shading="auto")
        ax.streamplot(xs, ys, u[..., 0], u[..., 1], color="white", linewidth=0.6, density=1.1, arrowsize=0.7)
        ax.set_title(f"{label} flow, t = {t:g} s")
    fig.colorbar(mesh, ax=axes[:2], label="speed |u| [m/s] (one scale for both)", shrink=0.9)
    err_mesh = axes[2].pcolormesh(xs, ys, error, cmap="magma", shading="auto")
    fig.colorbar(err_mesh, ax=axes[2], label="error |u_learned − u_true| [m/s]", shrink=0.9)
    axes[2].set_title(f"error; relative L2 over the data region {rel:.3%}")
    for ax in axes:
        ax.contour(xs, ys, covered.astype(float), levels=[0.5], colors="red", linewidths=1.2)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    axes[0].plot([], [], color="red", label="training data region")
    axes[0].legend(loc="upper right", fontsize=8, framealpha=0.8)
    return _save(fig, path, formats)


def learned_origin(eom: EquationsOfMotion | None) -> np.ndarray | None:
    """The point [m] a model's ``r`` is taken from, where it is not the coordinate origin."""
    if eom is None or eom.origin is None or not np.any(np.asarray(eom.origin)):
        return None
    return np.asarray(eom.origin)


def coefficient_figure(
    learned: AbstractCoefficients,
    truth: AbstractCoefficients | None,
    dataset: Dataset,
    path: Path,
    formats: tuple[str, ...] = ("png",),
    *,
    flow_of: EquationsOfMotion | None = None,
) -> list[Path]:
    """Learned (dots, coloured by r) and true (black) coefficients against σ at the (r, σ) the
    training data visits, one panel per coefficient. Without a truth (imported data) the learned
    ones alone, σ taken in the flow of ``flow_of`` (the learned equations)."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    eom = dataset.equations() if flow_of is None else flow_of
    points = visited_r_sigma(eom, dataset, max_points=3000)
    pts = jnp.asarray(points)
    got = np.asarray(coefficients_at(learned, pts))
    want = None if truth is None else np.asarray(coefficients_at(truth, pts))
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), layout="constrained")
    order = np.argsort(points[:, 1])
    lo, hi = points[:, 1].min(), points[:, 1].max()
    decades = np.arange(np.floor(np.log10(lo)), np.ceil(np.log10(hi)) + 1)
    ticks = [m * 10**d for d in decades for m in (1, 2, 5) if lo / 1.05 <= m * 10**d <= hi * 1.05]
    scatter = None
    for i, (ax, name) in enumerate(zip(axes.ravel(), COEFFICIENT_NAMES, strict=True)):
        scatter = ax.scatter(points[:, 1], got[:, i], s=4, c=points[:, 0], cmap="plasma", label="learned")
        if want is not None:
            ax.plot(points[order, 1], want[order, i], "k-", lw=2, label="true")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(FixedLocator(ticks))  # 1-2-5 ticks, plain labels: none collide
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("σ = |v − u| [m/s]")
        ax.set_ylabel(f"{name} [{UNITS[name]}]")
        ax.set_title(name)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    centre = learned_origin(flow_of)
    origin = "" if centre is None else f" from ({centre[0]:.3g}, {centre[1]:.3g}) m"
    fig.colorbar(scatter, ax=axes, label=f"r [m]{origin} (learned points)", shrink=0.8)
    return _save(fig, path, formats)


def rollout_figure(
    t: np.ndarray,
    truth: np.ndarray,
    predictions: dict[str, np.ndarray],
    path: Path,
    *,
    title: str = "",
    formats: tuple[str, ...] = ("png", "svg"),
) -> list[Path]:
    """Paths ``(x, y)`` of up to four test trajectories: truth (black) and every model's rollout.

    Args:
        t: sample times [s], shape ``(T,)``.
        truth: clean true states, shape ``(K, T, 4)``.
        predictions: model name → predicted states ``(K, T, 4)`` (non-finite where diverged).
    """
    k = min(4, truth.shape[0])
    fig, axes = plt.subplots(1, k, figsize=(4.2 * k, 4.8), squeeze=False, layout="constrained")
    for i, ax in enumerate(axes[0]):
        ax.plot(truth[i, :, 0], truth[i, :, 1], "k-", lw=2.2, label="truth")
        ax.plot(truth[i, 0, 0], truth[i, 0, 1], "ko")
        x, y = truth[i, :, 0], truth[i, :, 1]
        for name, pred in predictions.items():
            ax.plot(pred[i, :, 0], pred[i, :, 1], lw=1.1, label=name)
        # a square window around the truth, the same shape in every panel (models may leave it)
        half = 0.5 * max(np.ptp(x), np.ptp(y), 0.1) * 1.6
        cx, cy = 0.5 * (x.min() + x.max()), 0.5 * (y.min() + y.max())
        ax.set_xlim(cx - half, cx + half)
        ax.set_ylim(cy - half, cy + half)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f"test trajectory {i}, 0–{t[-1]:g} s")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8, frameon=False)
    if title:
        fig.suptitle(title)
    return _save(fig, path, formats)


def horizon_figure(
    horizons: list[float],
    curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]],
    path: Path,
    *,
    title: str = "",
    formats: tuple[str, ...] = ("png", "svg"),
) -> list[Path]:
    """Errors against horizon (the metrics registered with ``curve``), mean ± std over seeds.

    Args:
        horizons: horizons [s].
        curves: model → metric (each of :data:`~fhnn.evaluation.metrics.METRICS` with
            ``curve``) → (mean, std), arrays over ``horizons`` (NaN where every rollout diverged).
    """
    panels = [m for m in METRICS.values() if m.curve]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.5 * len(panels), 4.2), squeeze=False)
    axes = axes[0]
    h = np.asarray(horizons, dtype=float)
    for ax, metric in zip(axes, panels, strict=True):
        for name, metrics in curves.items():
            mean, std = metrics[metric.name]
            line = ax.plot(h, mean, "o-", ms=3, label=name)[0]
            ax.fill_between(h, mean - std, mean + std, color=line.get_color(), alpha=0.15, lw=0)
        ax.set_xscale("log")
        if not metric.fraction:
            ax.set_yscale("log")
        else:
            ax.set_ylim(-0.05, 1.05)
        ax.set_xlabel("horizon [s]")
        ax.set_title(metric.label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    if title:
        fig.suptitle(title)
    return _save(fig, path, formats)


def ablation_figure(
    names: list[str],
    mean: np.ndarray,
    std: np.ndarray,
    paper: list[float | None],
    path: Path,
    *,
    title: str = "",
    formats: tuple[str, ...] = ("png", "svg"),
) -> list[Path]:
    """RMSE(pos) at 5 s per FHNN variant as bars (log scale, ± std), the paper's as markers."""
    fig, ax = plt.subplots(figsize=(1.3 * len(names) + 2, 4.2))
    x = np.arange(len(names))
    shown = np.where(np.isfinite(mean), mean, np.nan)
    ax.bar(x, shown, yerr=np.where(np.isfinite(std), std, 0), capsize=3, color="tab:blue", label="ours")
    px = [i for i, p in enumerate(paper) if p is not None]
    ax.plot(px, [paper[i] for i in px], "r_", ms=22, mew=2.5, label="paper (its data)")
    for i in np.flatnonzero(~np.isfinite(mean)):
        ax.annotate(
            "diverged", (i, 1), xycoords=("data", "axes fraction"), ha="center", va="top", color="red"
        )
    ax.set_yscale("log")
    ax.set_xticks(x, names, rotation=20)
    ax.set_ylabel("RMSE(pos) at 5 s [m]")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    return _save(fig, path, formats)
