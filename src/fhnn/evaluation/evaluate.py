"""Evaluate a model on a split: rollouts, metrics at horizons, and how far rollouts extrapolate."""

from __future__ import annotations

from typing import Any

import numpy as np

from fhnn.data.dataset import Dataset
from fhnn.data.summary import coverage, relative_speeds
from fhnn.errors import ConfigError
from fhnn.evaluation.metrics import irregular_metrics, trajectory_metrics
from fhnn.models.base import AbstractModel


def evaluate(
    model: AbstractModel,
    dataset: Dataset,
    horizons: list[float],
    *,
    split: str = "test",
    include_zero: bool = False,
    both_averagings: bool = False,
    keep_rollout: bool = False,
) -> dict[str, Any]:
    """Metrics at each horizon, the per-trajectory divergence, and the fraction of rollouts that
    have left the (r, σ) range of the training data by each horizon.

    Args:
        model: the model to roll out (:meth:`~fhnn.models.base.AbstractModel.rollout`).
        dataset: the data set (its ``split`` is rolled out; its training split sets the region).
        horizons: whole seconds.
        split: "train", "val" or "test".
        include_zero: average over checkpoints ``t = 0, 1, …, H`` (the paper's way) instead of
            ``t = 1, …, H`` (docs/spec.md §5).
        both_averagings: also return the other averaging under ``"horizons_other"`` (one rollout).
        keep_rollout: also return the :class:`~fhnn.evaluation.rollout.Rollout` under ``"rollout"``.

    Returns:
        ``{"horizons": {H: {metric: value, "outside_training": fraction}}, "diverged": [bools],
        "split": split}``, plus the keys asked for.
    """
    data = dataset[split]
    if not horizons:
        raise ConfigError("give at least one horizon")
    longest = max(horizons)
    length = data.duration
    if longest > length + 1e-9:
        raise ConfigError(f"horizon {longest:g} s exceeds the {split} trajectories' length {length:g} s")
    ro = model.rollout(data, longest)
    size = ro.t.shape[-1]
    truth = data.states_clean[:, :size]
    train_cov = coverage(dataset, dataset.train)
    pred = np.where(np.isfinite(ro.states), ro.states, np.nan)
    offset = pred[..., :2] - dataset.centre
    r = np.hypot(offset[..., 0], offset[..., 1])
    if dataset.imported:  # no true flow: the region is (r, |v|)
        second, lo_hi = np.hypot(pred[..., 2], pred[..., 3]), train_cov["speed"]
    else:  # σ of the predicted states in the true flow
        sig = relative_speeds(dataset.equations(), np.nan_to_num(pred), ro.t)
        second, lo_hi = sig, train_cov["sigma"]
    r_lo, r_hi = train_cov["r"]
    outside_at = (r < r_lo) | (r > r_hi) | (second < lo_hi[0]) | (second > lo_hi[1]) | ~np.isfinite(r)
    rel = np.broadcast_to(ro.t - ro.t[..., :1], outside_at.shape)
    mask = np.ones(outside_at.shape, dtype=bool) if ro.mask is None else ro.mask

    def score(zero: bool) -> dict[str, Any]:
        results: dict[str, Any] = {}
        for h in horizons:
            if ro.mask is None:
                m = trajectory_metrics(ro.states, truth, ro.t, h, include_zero=zero)
            else:
                m = irregular_metrics(ro.states, truth, ro.t, ro.mask, h)
            upto = mask & (rel <= h + 1e-9)
            m["outside_training"] = float(np.mean(np.any(outside_at & upto, axis=1)))
            results[f"{h:g}"] = m
        return results

    out: dict[str, Any] = {"horizons": score(include_zero), "diverged": (~ro.ok).tolist(), "split": split}
    if both_averagings:
        out["horizons_other"] = score(not include_zero)
    if keep_rollout:
        out["rollout"] = ro
    return out


def evaluate_ensemble(
    models: list[AbstractModel], dataset: Dataset, horizons: list[float], *, split: str = "test"
) -> dict[str, Any]:
    """:func:`evaluate` for each member of an ensemble, and each metric's mean and standard
    deviation over the members (a member whose rollouts diverged contributes its error as
    :func:`evaluate` gives it, so an infinite error makes the mean infinite; ``diverged``, overall
    and under each horizon of ``mean``, is the members' total count of diverged trajectories).

    Returns:
        ``{"members": [evaluate(...) of each], "mean": {H: {metric: value}}, "std": {H: {...}},
        "diverged": total, "split": split}``.
    """
    if len(models) < 2:
        raise ConfigError(f"an ensemble has at least 2 members, got {len(models)}")
    members = [evaluate(m, dataset, horizons, split=split) for m in models]
    mean: dict[str, dict[str, float]] = {}
    std: dict[str, dict[str, float]] = {}
    for h, first in members[0]["horizons"].items():
        values = {k: np.array([m["horizons"][h][k] for m in members], dtype=float) for k in first}
        counts = values.pop("diverged")
        with np.errstate(invalid="ignore"):  # inf - inf in the std of diverged members: nan
            mean[h] = {k: float(np.mean(v)) for k, v in values.items()}
            std[h] = {k: float(np.std(v)) for k, v in values.items()}
        mean[h]["diverged"] = int(counts.sum())  # a count: the members' total, as in "diverged"
    diverged = int(sum(sum(m["diverged"]) for m in members))
    return {"members": members, "mean": mean, "std": std, "diverged": diverged, "split": split}
