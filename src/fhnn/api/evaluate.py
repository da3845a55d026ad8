"""``fhnn.evaluate``: errors of a run's (or ensemble's) rollouts at horizons, as ``fhnn evaluate``."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from fhnn.api.fit import Fit, as_fit
from fhnn.data.dataset import SPLITS, Dataset
from fhnn.errors import ConfigError
from fhnn.evaluation.evaluate import evaluate as evaluate_model
from fhnn.evaluation.evaluate import evaluate_ensemble
from fhnn.models.base import AbstractModel

#: Horizons [s] reported when none are given (those the trajectories allow).
DEFAULT_HORIZONS = (1, 2, 5, 16, 60)


@dataclass
class Evaluation:
    """Errors at horizons.

    Attributes:
        rows: ``{H: {metric: value}}`` (an ensemble: each metric's mean over the members).
        title: what was evaluated, in words.
        result: everything, as ``fhnn evaluate --json`` prints it (infinities as they are).
        notes: what is worth saying besides (e.g. which horizons the trajectories allow).
    """

    rows: dict[str, dict[str, float]]
    title: str
    result: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    def json(self) -> dict[str, Any]:
        """:attr:`result` as strict JSON values: a non-finite error (a diverged rollout) is ``None``."""
        return finite_or_null(self.result)

    def to_pandas(self) -> Any:
        """:attr:`rows` as a ``pandas.DataFrame``, one row per horizon [s]."""
        import pandas as pd

        return pd.DataFrame.from_dict(self.rows, orient="index")


def finite_or_null(value: Any) -> Any:
    """``value`` with every non-finite float (in nested dicts and lists) replaced by ``None``."""
    if isinstance(value, dict):
        return {k: finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_null(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def evaluate(
    run: Fit | AbstractModel | str | os.PathLike[str],
    data: Dataset | str | os.PathLike[str] | None = None,
    horizons: Sequence[float] | None = None,
    *,
    split: str = "test",
) -> Evaluation:
    """Roll the best model out from each trajectory's first state and report errors at horizons.

    Args:
        run: a :class:`~fhnn.api.fit.Fit`, a run or ensemble folder, or a model (then ``data`` is
            needed).
        data: the data set (default: the one the run was trained on).
        horizons: horizons [s] (default: those of 1, 2, 5, 16, 60 that the trajectories last).
        split: ``"train"``, ``"val"`` or ``"test"``.

    Returns:
        The :class:`Evaluation`.

    Raises:
        ConfigError: an unknown split, or horizons longer than the trajectories.
        DataFormatError: a missing or changed data set, or unreadable run files.
    """
    if split not in SPLITS:
        raise ConfigError(f"--split must be one of {', '.join(SPLITS)}, got {split!r}")
    if isinstance(run, AbstractModel):
        if data is None:
            raise ConfigError("evaluating a model needs its data set")
        fit = None
        models = [run]
        dataset = data if isinstance(data, Dataset) else as_dataset(data)
        notes: list[str] = []
        name = "model"
    else:
        fit = as_fit(run, data)
        models, dataset, notes, name = fit.models, fit.dataset, list(fit.notes), str(fit.folder)
    hs = [float(h) for h in horizons] if horizons is not None else []
    if horizons is None:
        length = dataset[split].duration
        hs = [float(h) for h in DEFAULT_HORIZONS if h <= length + 1e-9]
        if not hs:
            raise ConfigError(
                f"the {split} trajectories last {length:g} s, shorter than the shortest horizon (1 s)"
            )
        if len(hs) < len(DEFAULT_HORIZONS):
            notes.append(
                f"horizons {', '.join(f'{h:g}' for h in hs)} s: the {split} trajectories last {length:g} s "
                "(--horizons chooses others)"
            )
    if len(models) > 1:
        assert fit is not None
        ens = evaluate_ensemble(models, dataset, hs, split=split)
        n_traj = len(ens["members"][0]["diverged"])
        title = (
            f"ensemble {name} on {split} ({n_traj} trajectories): mean over its "
            f"{len(models)} members (diverged: their total; --json: each member and the std)"
        )
        result = {
            "mean": ens["mean"],
            "std": ens["std"],
            "members": {
                r.folder.name: {**m["horizons"], "diverged_count": int(sum(m["diverged"]))}
                for r, m in zip(fit.runs, ens["members"], strict=True)
            },
            "diverged_count": ens["diverged"],
        }
        return Evaluation(ens["mean"], title, result, notes)
    one = evaluate_model(models[0], dataset, hs, split=split)
    title = f"{name} on {split} ({len(one['diverged'])} trajectories)"
    return Evaluation(
        one["horizons"], title, {**one["horizons"], "diverged_count": int(sum(one["diverged"]))}, notes
    )


def as_dataset(data: str | os.PathLike[str]) -> Dataset:
    """The data set in the HDF5 file ``data``."""
    from fhnn.data.dataset import read_dataset

    return read_dataset(data)
