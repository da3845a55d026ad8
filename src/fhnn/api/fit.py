"""A trained run or ensemble with its data: what :func:`fhnn.train` returns and :func:`fhnn.load`
reads back, with the coefficients, the flow and forecasts a notebook user asks of it."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from fhnn.data.dataset import Dataset, read_dataset
from fhnn.errors import ConfigError
from fhnn.models.base import AbstractModel
from fhnn.training.ensemble import is_ensemble, member_folders
from fhnn.training.run import Run


class Fit:
    """A trained run, or the members of an ensemble, and the data set they go with.

    Args:
        runs: the run, or the ensemble's members.
        dataset: the data set (the one trained on, unless another was given).
        folder: the run's or the ensemble's folder.
        notes: what loading found worth saying (e.g. a guard stopped the run early).
    """

    def __init__(
        self, runs: list[Run], dataset: Dataset, folder: Path, notes: list[str] | None = None
    ) -> None:
        self.runs, self.dataset, self.folder = runs, dataset, Path(folder)
        self.notes = list(notes or [])

    def __repr__(self) -> str:
        what = f"ensemble of {len(self.runs)}" if self.is_ensemble else self.runs[0].kind
        return f"Fit({what}, folder={str(self.folder)!r})"

    @classmethod
    def load(
        cls, folder: str | os.PathLike[str], data: Dataset | str | os.PathLike[str] | None = None
    ) -> Fit:
        """The run or ensemble in ``folder``, with ``data`` (default: the data it was trained on).

        Raises:
            DataFormatError: not a run, unreadable files, or a data set missing or changed.
        """
        folder = Path(folder)
        runs = load_runs(folder)
        notes = []
        first = runs[0]
        if first.state is not None and first.state.stopped is not None:
            notes.append(f"note: {stopped_text(first)}")
        if isinstance(data, Dataset):
            dataset = data
        else:
            dataset = read_dataset(data) if data is not None else first.dataset()
        return cls(runs, dataset, folder, notes)

    @property
    def is_ensemble(self) -> bool:
        """Whether this is an ensemble (its members' spread gives intervals)."""
        return len(self.runs) > 1 or is_ensemble(self.folder)

    @property
    def run(self) -> Run:
        """The single run.

        Raises:
            ConfigError: on an ensemble.
        """
        if self.is_ensemble:
            members = ", ".join(str(r.folder) for r in self.runs)
            raise ConfigError(f"{self.folder} is an ensemble; give one of its runs ({members})")
        return self.runs[0]

    @property
    def models(self) -> list[AbstractModel]:
        """Each run's best model (by validation loss)."""
        return [r.best_model for r in self.runs]

    @property
    def best_model(self) -> AbstractModel:
        """The single run's best model."""
        return self.run.best_model

    def _fhnn(self) -> list[Any]:
        if any(r.kind != "fhnn" for r in self.runs):
            raise ConfigError(f"a {self.runs[0].kind!r} model has no flow or coefficients")
        return self.models

    def coefficients(self) -> Any:
        """The learned coefficients over the ``(r, σ)`` the training data cover.

        Returns:
            A ``pandas.DataFrame``: ``r`` [m], ``sigma`` [m/s], ``m_ax``, ``m_ay`` [kg], ``c_q``
            [–], ``c_l`` [N·s/m], ``drag`` [N·s/m]; for an ensemble the members' median and
            ``NAME_lo``, ``NAME_hi``, the ends of the 90 % interval.
        """
        import pandas as pd

        from fhnn.experiments.exports import coefficient_grid

        eoms = [m.eom for m in self._fhnn()]
        return pd.DataFrame(coefficient_grid(eoms if self.is_ensemble else eoms[0], self.dataset))

    def flow(self) -> Any:
        """The learned flow on a grid over the training positions.

        Returns:
            An ``xarray.Dataset`` with ``u``, ``v`` [m/s] and ``psi`` [m²/s] over ``y``, ``x`` [m]
            (and ``t`` for a time-dependent flow); for an ensemble the median and ``u_lo``, ``u_hi``, ….
        """
        from fhnn.experiments.exports import flow_dataset

        flows = [m.flow for m in self._fhnn()]
        return flow_dataset(flows if self.is_ensemble else flows[0], self.dataset)

    def predict(self, duration: float, **options: Any) -> Any:
        """A forecast: :func:`fhnn.predict` with this fit (``options`` as there)."""
        from fhnn.api.predict import predict

        return predict(self, duration, **options)

    def evaluate(self, **options: Any) -> Any:
        """Errors at horizons: :func:`fhnn.evaluate` with this fit (``options`` as there)."""
        from fhnn.api.evaluate import evaluate

        return evaluate(self, **options)

    def inspect(self, **options: Any) -> Any:
        """Coefficients, flow, notes and figures: :func:`fhnn.inspect` with this fit."""
        from fhnn.api.inspect import inspect

        return inspect(self, **options)


def load_runs(folder: str | os.PathLike[str]) -> list[Run]:
    """The run in ``folder``, or the members of the ensemble there (their data set not read)."""
    folder = Path(folder)
    return [Run.load(f) for f in (member_folders(folder) if is_ensemble(folder) else [folder])]


def stopped_text(run: Run) -> str:
    """The line saying that a guard stopped ``run`` early, and which model it kept."""
    state = run.state
    assert state is not None
    best = min(
        (r for r in state.history if r.get("val_total") == state.best_val),
        key=lambda r: r["step"],
        default={"step": "?"},
    )
    return (
        f"{state.stopped}; the result is the best model (validation loss {state.best_val:.3e}, "
        f"step {best['step']})"
    )


def as_fit(run: Fit | str | os.PathLike[str], data: Dataset | str | os.PathLike[str] | None = None) -> Fit:
    """``run`` as a :class:`Fit`: loaded from a folder, or a fit with other ``data``."""
    if isinstance(run, Fit):
        if data is None:
            return run
        dataset = data if isinstance(data, Dataset) else read_dataset(data)
        return Fit(run.runs, dataset, run.folder, run.notes)
    return Fit.load(run, data)


def load(folder: str | os.PathLike[str], data: Dataset | str | os.PathLike[str] | None = None) -> Fit:
    """The run or ensemble saved in ``folder`` (:meth:`Fit.load`)."""
    return Fit.load(folder, data)
