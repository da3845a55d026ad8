"""Laplace intervals of a run's coefficients and ratios from its whole-track fit's curvature, and
which of them the data leave undetermined (:mod:`fhnn.training.curvature`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.evaluation.recovery import SUMMARY_NAMES, coefficient_medians, visited_r_sigma
from fhnn.models.base import AbstractModel
from fhnn.physics.body import AbstractCoefficients
from fhnn.training.curvature import FLOOR, track_curvature
from fhnn.training.ensemble import LEVEL
from fhnn.training.tracks import fitted_pieces
from fhnn.training.train_config import TrainConfig


def laplace_intervals(
    model: AbstractModel,
    dataset: Dataset,
    train: TrainConfig,
    truth: AbstractCoefficients | None = None,
) -> dict[str, dict[str, Any]] | None:
    """Each of :data:`~fhnn.evaluation.recovery.SUMMARY_NAMES`' median over the covered ``(r, σ)``
    with its :data:`~fhnn.training.ensemble.LEVEL` Laplace interval from the curvature of the
    whole-track objective on the training tracks the run's fit used.

    Args:
        model: a trained FHNN.
        dataset: the data set it was trained on.
        train: the run's training settings (which pieces of the tracks its fit used).
        truth: the true coefficient law (simulated data), scored at the same ``(r, σ)``.

    Returns:
        Per quantity ``median``; ``lo``, ``hi`` and ``sd`` (``None`` where not determined: the
        interval wider than ``±|median|``); ``determined``; ``weak`` (its variance mostly from
        directions the data barely constrain, :data:`~fhnn.training.curvature.WEAK_SHARE`);
        with ``truth`` also ``true`` (its median) and ``inside`` (in the interval; ``None``
        where not determined). ``None`` for a model without whole-track parameters or tracks
        too short to fix them.
    """
    tables = laplace_tables(model, dataset, train, truth)
    return None if tables is None else tables[FLOOR]


def laplace_tables(
    model: AbstractModel,
    dataset: Dataset,
    train: TrainConfig,
    truth: AbstractCoefficients | None = None,
    floors: Sequence[float] = (FLOOR,),
) -> dict[float, dict[str, dict[str, Any]]] | None:
    """:func:`laplace_intervals` for each eigenvalue floor of ``floors`` (relative to the largest
    eigenvalue; :data:`~fhnn.training.curvature.FLOOR` by default) from one curvature: what the
    calibration benchmark compares."""
    if model.track_parameters() is None:
        return None
    pieces = fitted_pieces(dataset.train, train.track_samples, train.seed)[0]
    try:
        curvature = track_curvature(model, pieces)
    except ValueError:
        return None
    points = jnp.asarray(visited_r_sigma(model.eom, dataset))
    body = dataset.constants()
    true = None if truth is None else coefficient_medians(truth, points, body)
    return {
        floor: _table(
            curvature.intervals(
                lambda m: coefficient_medians(m.eom.coefficients, points, body), LEVEL, floor
            ),
            true,
        )
        for floor in floors
    }


def _table(found: dict[str, np.ndarray], true: jax.Array | None) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for i, name in enumerate(SUMMARY_NAMES):
        determined = bool(found["determined"][i])
        keep = (lambda x: float(x)) if determined else (lambda x: None)
        out[name] = {
            "median": float(found["value"][i]),
            "lo": keep(found["lo"][i]),
            "hi": keep(found["hi"][i]),
            "sd": keep(found["sd"][i]),
            "determined": determined,
            "weak": bool(found["weak"][i]),
        }
        if true is not None:
            t = float(true[i])
            out[name]["true"] = t
            out[name]["inside"] = bool(found["lo"][i] <= t <= found["hi"][i]) if determined else None
    return out


def identifiability_note(intervals: dict[str, dict[str, Any]]) -> str | None:
    """What the fit's curvature says the data leave undetermined, in words (``None``: every
    quantity determined, none weakly)."""
    lost = [n for n, v in intervals.items() if not v["determined"]]
    weak = [n for n, v in intervals.items() if v["determined"] and v["weak"]]
    if not lost and not weak:
        return None
    fixed = {n for n, v in intervals.items() if v["determined"] and not v["weak"]}
    why = []
    if {"m_ax", "m_ay"} & set(lost) and all(n in fixed for n in intervals if "/" in n):
        why.append("inertia and drag scale together (no known force fixes their size)")
    if {"c_l", "c_q"} & set(lost + weak) and "drag" in fixed:
        why.append("c_l and c_q trade against each other at slow speeds while their sum, the drag, is fixed")
    parts = []
    if lost:
        parts.append(f"the data do not determine {', '.join(lost)} (no interval given)")
    if weak:
        parts.append(
            f"{', '.join(weak)} {'rests' if len(weak) == 1 else 'rest'} on directions the data barely "
            "constrain (interval marked weak: it depends on how little curvature is assumed there)"
        )
    reason = f" — {'; '.join(why)}" if why else ""
    return "identifiability, from the whole-track fit's curvature: " + "; ".join(parts) + reason + "."


__all__ = ["identifiability_note", "laplace_intervals", "laplace_tables"]
