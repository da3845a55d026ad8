"""Figures of a body that turns: forecast against truth, the body's outline drawn at intervals."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Polygon

from fhnn.data.planar import PlanarDataset
from fhnn.evaluation.planar import forecast
from fhnn.files import atomic_output
from fhnn.models.planar import PlanarFHNN


def outline(pose: np.ndarray, length: float) -> np.ndarray:
    """A pointed hull of ``length`` [m] (beam a quarter of it) at ``pose = (x, y, ψ)``, its bow
    along ψ: the polygon's corners, shape ``(5, 2)`` [m]."""
    half, beam = 0.5 * length, 0.125 * length
    body = np.array([[half, 0.0], [0.2 * half, beam], [-half, beam], [-half, -beam], [0.2 * half, -beam]])
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return body @ np.array([[c, s], [-s, c]]) + pose[:2]


def forecast_figure(
    model: PlanarFHNN,
    dataset: PlanarDataset,
    path: str | os.PathLike[str],
    *,
    horizon: float = 5.0,
    trajectories: int = 4,
    every: float = 1.0,
) -> Path:
    """Draw the first ``trajectories`` test trajectories to ``horizon`` [s], the reference (grey:
    a simulation's truth, an import's observations) and the forecast (blue), with the body's
    outline at the samples nearest every ``every`` seconds, and write a PNG to ``path``.

    Returns:
        The path written.
    """
    test = dataset.splits["test"]
    pred, _ = forecast(model, test, horizon)
    n = min(trajectories, pred.shape[0])
    reference = "truth" if dataset.has_truth else "observed"
    shown = [(test.t[i, : pred.shape[1]] - test.t[i, 0]) <= horizon + 1e-9 for i in range(n)]
    points = [test.states_clean[i, : pred.shape[1]][shown[i], :2] for i in range(n)]
    span = np.ptp(np.concatenate(points), axis=0)
    length = 0.06 * max(span.max(), 1e-3)
    fig, ax = plt.subplots(figsize=(6.5, 6.0))
    for i in range(n):
        t = test.t[i, : pred.shape[1]][shown[i]] - test.t[i, 0]
        marks = np.unique([np.argmin(np.abs(t - m)) for m in np.arange(0.0, t[-1] + 1e-9, every)])
        drawn = (
            (test.states_clean[i, : t.size], "-", "0.55", reference),
            (pred[i, : t.size], "--", "tab:blue", "forecast"),
        )
        for states, style, colour, label in drawn:
            ax.plot(states[:, 0], states[:, 1], style, color=colour, lw=1.0, label=label if i == 0 else None)
            for k in marks:
                if np.all(np.isfinite(states[k, :3])):
                    hull = Polygon(outline(states[k, :3], length), closed=True, fc="none", ec=colour, lw=0.8)
                    ax.add_patch(hull)
    if dataset.has_truth:
        ax.plot([0.0], [0.0], "k+", ms=8, label="vortex centre")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    title = f"{dataset.scenario}: test forecasts to {horizon:g} s, outline every {every:g} s"
    ax.set_title(title, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    with atomic_output(Path(path).with_suffix(".png")) as tmp:
        fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png")
    plt.close(fig)
    return Path(path).with_suffix(".png")


__all__ = ["forecast_figure", "outline"]
