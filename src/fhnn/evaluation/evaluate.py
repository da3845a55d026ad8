"""Evaluate a model on a split: rollouts, metrics at horizons, and how far rollouts extrapolate."""

from __future__ import annotations

from typing import Any

import numpy as np

from fhnn.data.dataset import Dataset, samples_until
from fhnn.data.summary import coverage, relative_speeds
from fhnn.errors import ConfigError
from fhnn.evaluation.metrics import trajectory_metrics
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
            ``t = 1, …, H`` (SPEC §5).
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
    if longest > data.t[-1] + 1e-9:
        raise ConfigError(f"horizon {longest:g} s exceeds the {split} trajectories' length {data.t[-1]:g} s")
    ro = model.rollout(data, longest)
    truth = data.states_clean[:, : ro.t.size]
    eom = dataset.equations()
    train_cov = coverage(eom, dataset.train)
    r_lo, r_hi = train_cov["r"]
    s_lo, s_hi = train_cov["sigma"]
    pred = np.where(np.isfinite(ro.states), ro.states, np.nan)
    r = np.hypot(pred[..., 0], pred[..., 1])
    sig = relative_speeds(eom, np.nan_to_num(pred), ro.t)  # σ of the predicted states in the true flow
    outside_at = (r < r_lo) | (r > r_hi) | (sig < s_lo) | (sig > s_hi) | ~np.isfinite(r)

    def score(zero: bool) -> dict[str, Any]:
        results: dict[str, Any] = {}
        for h in horizons:
            m = trajectory_metrics(ro.states, truth, ro.t, h, include_zero=zero)
            upto = samples_until(ro.t, h)
            m["outside_training"] = float(np.mean(np.any(outside_at[:, :upto], axis=1)))
            results[f"{h:g}"] = m
        return results

    out: dict[str, Any] = {"horizons": score(include_zero), "diverged": (~ro.ok).tolist(), "split": split}
    if both_averagings:
        out["horizons_other"] = score(not include_zero)
    if keep_rollout:
        out["rollout"] = ro
    return out
