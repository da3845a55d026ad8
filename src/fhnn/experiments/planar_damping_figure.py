"""The learned damping of a body that turns, drawn per axis against its own relative velocity."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from fhnn.evaluation.planar_coefficients import AXES
from fhnn.files import atomic_output


def damping_figure(samples: dict[str, np.ndarray], path: str | os.PathLike[str]) -> Path:
    """Three panels, surge, sway and yaw: the damping force or moment at each covered relative
    velocity (:func:`fhnn.evaluation.planar_coefficients.damping_samples`) against that axis's
    relative velocity, learned (blue; with ``X_d_lo`` and ``X_d_hi`` and the like, an ensemble's
    interval as a bar at each point) and, where ``samples`` has it, true (grey); writes a PNG to
    ``path`` and returns its path. The other axes' velocities vary along each panel's points, so a
    panel is a cloud, not a curve, where the damping couples them."""
    fig, axes = plt.subplots(1, 3, figsize=(11.0, 3.4))
    for ax, (speed, speed_unit, force, force_unit) in zip(axes, AXES, strict=True):
        x = samples[speed]
        if f"true_{force}" in samples:
            ax.plot(x, samples[f"true_{force}"], ".", color="0.6", ms=3, label="true")
        if f"{force}_lo" in samples:
            ax.vlines(x, samples[f"{force}_lo"], samples[f"{force}_hi"], color="tab:blue", lw=0.6, alpha=0.3)
        ax.plot(x, samples[force], ".", color="tab:blue", ms=2, label="learned")
        ax.set_xlabel(f"{speed} [{speed_unit}]")
        ax.set_ylabel(f"{force} [{force_unit}]")
        ax.axhline(0.0, color="0.85", lw=0.8, zorder=0)
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle("damping over the relative velocities the training data cover", fontsize=10)
    fig.tight_layout()
    target = Path(path).with_suffix(".png")
    with atomic_output(target) as tmp:
        fig.savefig(tmp, dpi=130, bbox_inches="tight", format="png")
    plt.close(fig)
    return target


__all__ = ["damping_figure"]
