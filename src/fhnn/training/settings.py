"""One resolver of a training run's settings, used by ``fhnn train`` and :func:`fhnn.train` alike.

Precedence, lowest first: the configuration classes' defaults < the plan (named, or the default
plan for the data) < what the data imply (:func:`~fhnn.training.plans.data_settings`) < a
settings file < explicit settings (``--set`` and the dedicated options). The notes a command
prints about what the data changed come from :class:`Resolution`, not from re-reading plans.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fhnn.config import coerce, get_setting, read_settings_file
from fhnn.data.dataset import Dataset
from fhnn.errors import ConfigError
from fhnn.models.registry import MODELS
from fhnn.training.plans import DEFAULT_PLAN, data_settings, default_settings, get_plan, is_noisy
from fhnn.training.run import RunConfig


def parse_params(items: list[str], option: str = "--set") -> dict[str, str]:
    """``["NAME=VALUE", ...]`` → ``{NAME: VALUE}``.

    Raises:
        ConfigError: an item without ``=``, a name or a value (the message names ``option``).
    """
    params: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise ConfigError(f"{option} expects NAME=VALUE, got {item!r}")
        params[name.strip()] = value.strip()
    return params


def given_settings(
    settings: Mapping[str, Any] | None = None,
    config_file: str | os.PathLike[str] | None = None,
    flags: Mapping[str, tuple[str, Any]] | None = None,
) -> dict[str, Any]:
    """The explicit settings of a command, by dotted name.

    Args:
        settings: explicit settings (``--set``); they win over ``config_file``.
        config_file: a TOML or JSON settings file.
        flags: setting name → (the option's name, its value or ``None``): dedicated options.

    Raises:
        ConfigError: an option that disagrees with the same setting given otherwise.
    """
    out: dict[str, Any] = read_settings_file(config_file) if config_file is not None else {}
    out.update(settings or {})
    for name, (flag, value) in (flags or {}).items():
        if value is None:
            continue
        if name in out and str(out[name]) != str(value):
            try:
                same = coerce(type(value), out[name], name) == value
            except ConfigError:
                same = False
            if not same:
                raise ConfigError(f"{flag} {value} and the setting {name}={out[name]} disagree; give one")
        out[name] = value
    return out


def check_settings(settings: Mapping[str, Any], plan: str | None = None) -> str:
    """Check ``settings`` (and ``plan``) before any data are read; returns the model kind.

    Raises:
        ConfigError: an unknown kind, plan, setting or value.
    """
    kind = str(settings.get("kind", "fhnn"))
    MODELS[kind]  # unknown kinds are refused before anything is read
    if "model.ablation" in settings and settings["model.ablation"] != "none" and kind != "fhnn":
        raise ConfigError(f"--ablation applies to fhnn only, not {kind!r}")
    RunConfig().with_settings({**(get_plan(plan).settings(kind) if plan is not None else {}), **settings})
    return kind


@dataclass(frozen=True)
class Resolution:
    """The settings of a run resolved for its data.

    Attributes:
        kind: the model kind.
        settings: the plan's settings below the explicit ones: what a resumed run is compared
            with (its stored settings stand for the rest).
        start: the default plan's settings (a new run without a named plan), else empty.
        implied: what the data imply, less what was given.
        config: the configuration of a new run.
        notes: what the data changed, in words (empty for a resumed run).
    """

    kind: str
    settings: dict[str, Any]
    start: dict[str, Any]
    implied: dict[str, Any]
    config: RunConfig
    notes: list[str] = field(default_factory=list)

    def member(self, seed: int) -> tuple[dict[str, Any], RunConfig]:
        """An ensemble member's settings and new-run configuration, at ``train.seed=seed``."""
        settings = {**self.settings, "train.seed": seed}
        return settings, RunConfig().with_settings({**self.start, **settings, **self.implied})


def resolve(
    dataset: Dataset,
    settings: Mapping[str, Any],
    *,
    plan: str | None = None,
    fresh: bool = True,
    source: str = "",
) -> Resolution:
    """Resolve the explicit ``settings`` of a run on ``dataset``.

    Args:
        dataset: the training data.
        settings: explicit settings by dotted name (:func:`given_settings`).
        plan: a plan of :data:`~fhnn.training.plans.PLANS` (``None``: the default plan for the data).
        fresh: whether the run is new (notes and the default plan apply to new runs only).
        source: how the notes name the data (e.g. its path).

    Raises:
        ConfigError: an unknown kind, plan, setting or value.
    """
    kind = check_settings(settings, plan)
    given = set(settings)
    merged = dict(settings)
    if plan is not None:  # the plan's settings for these data, below any setting given
        merged = {**get_plan(plan).settings(kind), **merged}
    start = default_settings(dataset, kind) if plan is None else {}
    implied = {k: v for k, v in data_settings(dataset, kind).items() if k not in given}
    before = RunConfig().with_settings({**start, **merged})
    config = RunConfig().with_settings({**start, **merged, **implied})
    notes: list[str] = []
    if fresh:
        said = {k: v for k, v in implied.items() if get_setting(before, k) != get_setting(config, k)}
        said.pop("model.slow_weight", None)  # said by the window weights' note
        notes = _implied_notes(said, dataset, source)
        if kind == "fhnn" and "model.slow_weight" not in given and plan in (None, DEFAULT_PLAN):
            notes += _window_weights_note(source, dataset, config)
    return Resolution(kind, merged, start, implied, config, notes)


def _implied_notes(said: dict[str, Any], dataset: Dataset, source: str) -> list[str]:
    """What the settings the data imply changed, in words."""
    notes = []
    masses = said.pop("model.added_mass", None)
    if masses is not None:
        notes.append(
            f"{source}: no known forcing: the added masses are not identifiable, only c/(M + m_a); "
            f"training with model.added_mass={masses} (--set wins)"
        )
    if said:
        estimated = [f for f in ("velocities", "derivatives") if f not in dataset.measured]
        with_ = ", ".join(f"{k}={v}" for k, v in said.items())
        fields = " and ".join(estimated)
        notes.append(f"{source}: {fields} were estimated, not measured: training with {with_} (--set wins)")
    return notes


def _window_weights_note(source: str, dataset: Dataset, config: RunConfig) -> list[str]:
    """Whether a new FHNN run weighs its windows by their slowness, and why: a line, or none."""
    weight = float(config.model.slow_weight)  # type: ignore[union-attr]
    if weight > 0:
        text = f"noise-free observations: each window weighted by its slowness (model.slow_weight={weight:g})"
    elif is_noisy(dataset):
        text = (
            f"observations with noise (obs_noise {dataset.obs_noise:.3g}): windows not weighted by their "
            "slowness (model.slow_weight=0; the default plan weighs them on noise-free observations only)"
        )
    else:
        return []
    return [f"{source}: {text} (--set wins)"]


def source_name(data: Dataset | str | os.PathLike[str]) -> str:
    """How notes name a data set: its path, or ``"data"`` for one in memory."""
    return str(data) if isinstance(data, str | os.PathLike | Path) else "data"
