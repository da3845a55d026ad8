"""Figures: learned vs true flow (quiver and streamlines), coefficients, rollouts.

All functions draw with matplotlib's non-interactive Agg backend and write PNG (and SVG where
asked) files; they return the paths written.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.evaluation.recovery import visited_r_sigma
from fhnn.physics.body import COEFFICIENT_NAMES, AbstractCoefficients
from fhnn.physics.flows import AbstractFlow

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
    u = np.asarray(jax.vmap(flow.velocity, in_axes=(0, None))(pts, t))
    return u.reshape(ys.size, xs.size, 2)


def flow_figure(
    learned: AbstractFlow,
    truth: AbstractFlow,
    dataset: Dataset,
    path: Path,
    *,
    t: float = 0.0,
    formats: tuple[str, ...] = ("png",),
) -> list[Path]:
    """Four panels: quiver (true, learned), streamlines (true, learned) over the training region."""
    pos = dataset.train.states_clean[..., :2].reshape(-1, 2)
    lo, hi = pos.min(axis=0), pos.max(axis=0)
    pad = 0.05 * (hi - lo)
    xs = np.linspace(lo[0] - pad[0], hi[0] + pad[0], 25)
    ys = np.linspace(lo[1] - pad[1], hi[1] + pad[1], 25)
    fields = {"true": _velocity_grid(truth, xs, ys, t), "learned": _velocity_grid(learned, xs, ys, t)}
    fig, axes = plt.subplots(2, 2, figsize=(10, 9))
    for col, (label, u) in enumerate(fields.items()):
        speed = np.hypot(u[..., 0], u[..., 1])
        ax = axes[0, col]
        ax.quiver(xs, ys, u[..., 0], u[..., 1], speed, cmap="viridis")
        ax.set_title(f"{label} flow (quiver), t = {t:g} s")
        ax = axes[1, col]
        strm = ax.streamplot(xs, ys, u[..., 0], u[..., 1], color=speed, cmap="viridis", density=1.2)
        fig.colorbar(strm.lines, ax=ax, label="|u| [m/s]")
        ax.set_title(f"{label} flow (streamlines)")
        for a in axes[:, col]:
            a.plot(pos[::50, 0], pos[::50, 1], ",", color="0.6")
            a.set_aspect("equal")
            a.set_xlabel("x [m]")
            a.set_ylabel("y [m]")
    return _save(fig, path, formats)


def coefficient_figure(
    learned: AbstractCoefficients,
    truth: AbstractCoefficients,
    dataset: Dataset,
    path: Path,
    formats: tuple[str, ...] = ("png",),
) -> list[Path]:
    """Learned and true coefficients against σ at the (r, σ) the training data visits."""
    points = visited_r_sigma(dataset.equations(), dataset, max_points=3000)
    pts = jnp.asarray(points)
    got = np.asarray(jax.vmap(learned)(pts[:, 0], pts[:, 1]))
    want = np.asarray(jax.vmap(truth)(pts[:, 0], pts[:, 1]))
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
    order = np.argsort(points[:, 1])
    for i, (ax, name) in enumerate(zip(axes, COEFFICIENT_NAMES, strict=True)):
        ax.plot(points[order, 1], want[order, i], "k-", lw=2, label="true")
        ax.scatter(points[:, 1], got[:, i], s=3, c=points[:, 0], cmap="plasma", label="learned (colour: r)")
        ax.set_xscale("log")
        ax.set_xlabel("σ [m/s]")
        ax.set_title(f"{name} [{UNITS[name]}]")
    axes[0].legend(fontsize=8)
    return _save(fig, path, formats)
