"""Every model kind, in one table: what training, the reproduction grid, the tables, the CLI and
the benchmarks know about a model comes from here.

An entry (:class:`ModelKind`) names a kind, its label in tables, its configuration class, how its
data-derived build arguments are computed from a data set, how a fresh model is built from
``(config, arguments, key)``, optionally a one-shot ``fit`` that replaces gradient descent (SINDy's
sparse regression), and whether the paper has it. Adding a model is one new file in
``fhnn/models/`` and one entry in :data:`MODELS`; the contract test
(``tests/test_registry.py``) then takes it through build, training, checkpoint, rollout and
metrics.
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import jax

from fhnn.config import Config
from fhnn.data.dataset import Dataset
from fhnn.errors import ConfigError
from fhnn.models.base import AbstractModel
from fhnn.models.baselines import MLPConfig, build_baseline, data_statistics
from fhnn.models.dhn import DHNConfig, build_dhn
from fhnn.models.fhnn import ABLATIONS, FHNNConfig, build_fhnn, fhnn_arguments
from fhnn.models.sindy import SINDyConfig, empty_sindy, fit_sindy

#: ``build(config, arguments, key)`` → a fresh model.
Builder = Callable[[Any, dict[str, Any], jax.Array], AbstractModel]
#: ``fit(config, dataset)`` → ``(fitted model, extra record fields)``.
Fitter = Callable[[Any, Dataset], tuple[AbstractModel, dict[str, Any]]]


@dataclass(frozen=True)
class ModelKind:
    """One model kind.

    Attributes:
        name: the kind's name (``--model NAME``, ``run.json``'s ``model``).
        label: its name in tables and figures.
        summary: one line for ``--help``.
        config: its configuration class (a :class:`~fhnn.config.Config`).
        build: ``(config, arguments, key)`` → a fresh model.
        arguments: data set → the data-derived, JSON-serialisable build arguments (stored in the
            run folder, so a checkpoint rebuilds without the data).
        fit: a one-shot fit replacing gradient descent, or ``None`` (trained by the trainer).
        in_paper: whether the paper compares against it (the quick reproduction runs only those).
        variants: named variants of the kind (FHNN's ablations): name → label.
        stored_defaults: configuration fields added after runs of the kind were first stored,
            with the value that builds the model such a run saved (a field missing from a stored
            configuration takes it, not the current default).
    """

    name: str
    label: str
    summary: str
    config: type[Config]
    build: Builder
    arguments: Callable[[Dataset], dict[str, Any]]
    fit: Fitter | None = None
    in_paper: bool = True
    variants: Mapping[str, str] = field(default_factory=dict)
    stored_defaults: Mapping[str, Any] = field(default_factory=dict)

    def default_config(self) -> Config:
        return self.config()

    def make(self, config: Config, arguments: dict[str, Any], seed: int) -> AbstractModel:
        """A fresh model from its configuration, build arguments and seed."""
        return self.build(config, arguments, jax.random.PRNGKey(seed))


class Registry(Mapping[str, ModelKind]):
    """The model kinds by name, in table order; unknown names are refused with a suggestion."""

    def __init__(self, kinds: list[ModelKind]) -> None:
        self._kinds = {k.name: k for k in kinds}

    def __getitem__(self, name: str) -> ModelKind:
        if name not in self._kinds:
            close = difflib.get_close_matches(str(name), list(self._kinds), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(f"unknown model {name!r}{hint}; available: {', '.join(self._kinds)}")
        return self._kinds[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._kinds)

    def __len__(self) -> int:
        return len(self._kinds)

    def __contains__(self, name: object) -> bool:
        return name in self._kinds

    def register(self, kind: ModelKind) -> ModelKind:
        """Add model kind ``kind`` (after those already there); returns it.

        Raises:
            ConfigError: a name already registered.
        """
        if kind.name in self._kinds:
            raise ConfigError(f"a model kind named {kind.name!r} is already registered")
        self._kinds[kind.name] = kind
        return kind

    def labels(self) -> dict[str, str]:
        """Every kind's and variant's label, by name."""
        out = {k.name: k.label for k in self._kinds.values()}
        for kind in self._kinds.values():
            out.update(kind.variants)
        return out

    def variants(self) -> dict[str, str]:
        """Every variant name → the kind it belongs to."""
        return {v: k.name for k in self._kinds.values() for v in k.variants}


def _fhnn(config: FHNNConfig, args: dict[str, Any], key: jax.Array) -> AbstractModel:
    return build_fhnn(config, **args, key=key)


def _baseline(kind: str) -> Builder:
    return lambda config, args, key: build_baseline(kind, config, args, key)


def _dhn(config: DHNConfig, args: dict[str, Any], key: jax.Array) -> AbstractModel:
    return build_dhn(config, args, args["n_traj"], key)


def _dhn_arguments(dataset: Dataset) -> dict[str, Any]:
    if not dataset.train.regular:
        raise ConfigError("the DHN needs trajectories sampled at common, regular times (it steps in blocks)")
    return data_statistics(dataset)


def _sindy(config: SINDyConfig, args: dict[str, Any], key: jax.Array) -> AbstractModel:
    return empty_sindy(config)


def _fit_sindy(config: SINDyConfig, dataset: Dataset) -> tuple[AbstractModel, dict[str, Any]]:
    model, equations = fit_sindy(config, dataset.train)
    return model, {"equations": equations}


MODELS = Registry(
    [
        ModelKind(
            "fhnn",
            "FHNN",
            "learned stream function and coefficient laws inside the equations of motion",
            FHNNConfig,
            _fhnn,
            fhnn_arguments,
            variants=ABLATIONS,
            # runs stored before the harmonic time basis had the paper's ψ(x, y, t); before the
            # data-derived centre, r was taken from the table's origin
            stored_defaults={"time_modes": 0, "centre": "origin"},
        ),
        ModelKind("node", "Neural ODE", "MLP (s, F) → ṡ", MLPConfig, _baseline("node"), data_statistics),
        ModelKind("hnn", "HNN", "Hamiltonian H(q, p)", MLPConfig, _baseline("hnn"), data_statistics),
        ModelKind("lnn", "LNN", "Lagrangian L(q, q̇)", MLPConfig, _baseline("lnn"), data_statistics),
        ModelKind("dhn", "DHN", "denoising Hamiltonian network", DHNConfig, _dhn, _dhn_arguments),
        ModelKind(
            "dhnn",
            "dissipative HNN",
            "Hamiltonian plus Rayleigh dissipation",
            MLPConfig,
            _baseline("dhnn"),
            data_statistics,
            in_paper=False,
        ),
        ModelKind(
            "sindy",
            "SINDy",
            "sparse polynomial regression (PySINDy)",
            SINDyConfig,
            _sindy,
            data_statistics,
            fit=_fit_sindy,
            in_paper=False,
        ),
    ]
)

__all__ = ["MODELS", "ModelKind", "Registry"]
