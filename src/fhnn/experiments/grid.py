"""The reproduction as a grid of independent jobs (SPEC §6).

Two kinds of job:

- a **data job** simulates one data set (a scenario at the reproduction's data settings);
- a **model job** trains one model (FHNN, an ablation or a baseline) on one data set with one seed,
  then evaluates it (metrics at every horizon the tables and figures need, in both averagings,
  the first four test rollouts, and for FHNN the parameter and flow recovery).

Every job is identified by a hash of everything that determines its result (its specification,
the data set's specification and the package version), so a finished job is recognised and
skipped however the grid around it changed, and a changed setting never reuses a stale result.

Which jobs the tables need (``S`` = seeds):

- T1, T2, T3, T5 on each of ``main_scenarios``: every model of ``models`` and FHNN's ``ablations``;
- T4: FHNN on each of ``scenario_table`` (shared with the main scenarios where they coincide);
- T6: FHNN's recovery on the main scenarios, and on ``steady_vortex`` without actuation (the
  identifiability contrast), when ``identifiability`` is set.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

from fhnn import __version__
from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.errors import ConfigError
from fhnn.physics.scenarios import PAPER_SCENARIOS, SCENARIOS
from fhnn.training.run import MODELS

#: Horizons [s] every model is evaluated at: T1 (1–4, 8, 16), T2 (1, 5), T3 (30, 60, 120), T4/T5 (5).
HORIZONS = (1, 2, 3, 4, 5, 8, 16, 30, 60, 120)
ABLATIONS = ("no_added_mass", "no_linear_drag", "no_flow", "shallow", "relu")
BASELINES = ("node", "hnn", "lnn", "dhn", "dhnn", "sindy")


@frozen_config
class ReproduceConfig(Config):
    """What ``fhnn reproduce`` runs.

    Attributes:
        seeds: training seeds per model (each table cell is the mean ± std over them).
        steps: Adam steps of every gradient-trained model (the same budget for all).
        lbfgs_steps: L-BFGS polish iterations after Adam (FHNN only; 0 = none).
        batch_size: transition pairs per Adam step.
        val_every: steps between validations.
        n_traj: trajectories per data set (``None``: each scenario's default, SPEC §3).
        duration: length of train and val trajectories [s] (``None``: the scenario's default).
        dt: sampling interval [s] (``None``: the scenario's default).
        test_duration: length of test trajectories [s]; at least the longest horizon (120 s).
        data_seed: seed of every simulated data set.
        models: models of T1/T2 (``fhnn`` plus baselines of ``node, hnn, lnn, dhn, dhnn, sindy``).
        ablations: FHNN ablations of T5.
        main_scenarios: scenarios of T1, T2, T3, T5 and the figures.
        scenario_table: scenarios of T4.
        identifiability: add ``steady_vortex`` without actuation to T6.
    """

    config_name = "reproduce"

    seeds: int = 3
    steps: int = 1500
    lbfgs_steps: int = 0
    batch_size: int = 256
    val_every: int = 500
    n_traj: int | None = None
    duration: float | None = None
    dt: float | None = None
    test_duration: float = 120.0
    data_seed: int = 0
    models: tuple[str, ...] = ("fhnn", *BASELINES)
    ablations: tuple[str, ...] = ABLATIONS
    main_scenarios: tuple[str, ...] = ("solid_body_vortex", "steady_vortex")
    scenario_table: tuple[str, ...] = PAPER_SCENARIOS
    identifiability: bool = True

    def validate(self) -> None:
        check_positive(self, "seeds", "steps", "batch_size", "val_every", "test_duration")
        check_nonnegative(self, "lbfgs_steps", "data_seed")
        if self.n_traj is not None and self.n_traj < 3:
            raise ConfigError(f"reproduce: n_traj must be >= 3 (one per split), got {self.n_traj}")
        for name in ("duration", "dt"):
            value = getattr(self, name)
            if value is not None and value <= 0:
                raise ConfigError(f"reproduce: {name} must be > 0, got {value}")
        if self.test_duration < max(HORIZONS):
            raise ConfigError(
                f"reproduce: test_duration must cover the longest horizon ({max(HORIZONS)} s), "
                f"got {self.test_duration}"
            )
        _check_names("models", self.models, MODELS)
        _check_names("ablations", self.ablations, ABLATIONS)
        _check_names("main_scenarios", self.main_scenarios, SCENARIOS)
        _check_names("scenario_table", self.scenario_table, SCENARIOS)
        if not (self.models or self.scenario_table):
            raise ConfigError("reproduce: nothing to run (models and scenario_table are both empty)")

    @classmethod
    def quick(cls, **overrides: Any) -> ReproduceConfig:
        """Small data sampled at 0.1 s, 80 steps, one seed, the paper's models only, T1/T2/T3/T5 on
        ``solid_body_vortex`` only and no identifiability contrast: the whole report in a few
        minutes on 2 cores (every table and figure present and well-formed; the numbers are far
        from converged)."""
        base = {
            "seeds": 1,
            "steps": 80,
            "val_every": 40,
            "n_traj": 20,
            "duration": 3.0,
            "dt": 0.1,
            "main_scenarios": ("solid_body_vortex",),
            "models": ("fhnn", "node", "hnn", "lnn", "dhn"),
            "identifiability": False,
        }
        return cls.from_dict({**base, **overrides})


def _check_names(what: str, names: tuple[str, ...], valid: Any) -> None:
    for name in names:
        if name not in valid:
            raise ConfigError(f"reproduce: unknown name {name!r} in {what}; valid: {', '.join(valid)}")
    if len(set(names)) != len(names):
        raise ConfigError(f"reproduce: {what} lists a name twice: {', '.join(names)}")


def _digest(spec: dict[str, Any]) -> str:
    text = json.dumps({**spec, "version": __version__}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class DataJob:
    """Simulate ``scenario`` with the simulation settings ``settings`` (SimulationConfig fields)."""

    scenario: str
    settings: dict[str, Any] = field(hash=False)

    @property
    def label(self) -> str:
        return self.scenario + ("_noact" if self.settings.get("actuation") == "none" else "")

    @property
    def spec(self) -> dict[str, Any]:
        return {"kind": "data", "scenario": self.scenario, "settings": self.settings}

    @property
    def id(self) -> str:
        return f"{self.label}-{_digest(self.spec)}"

    @property
    def filename(self) -> str:
        return f"{self.id}.h5"


@dataclass(frozen=True)
class ModelJob:
    """Train model ``model`` (FHNN ``ablation``) with ``seed`` on ``data``, then evaluate it."""

    data: DataJob
    model: str
    ablation: str
    seed: int
    train: dict[str, Any] = field(hash=False)

    @property
    def variant(self) -> str:
        """``fhnn``, an ablation's name, or a baseline's name."""
        return self.ablation if self.ablation != "none" else self.model

    @property
    def label(self) -> str:
        return f"{self.data.label}__{self.variant}__s{self.seed}"

    @property
    def spec(self) -> dict[str, Any]:
        return {
            "kind": "model",
            "data": self.data.spec,
            "model": self.model,
            "ablation": self.ablation,
            "seed": self.seed,
            "train": self.train,
            "horizons": list(HORIZONS),
        }

    @property
    def id(self) -> str:
        return f"{self.label}-{_digest(self.spec)}"


def data_job(config: ReproduceConfig, scenario: str, *, actuation: str | None = None) -> DataJob:
    """The data set of ``scenario`` at the reproduction's settings."""
    settings: dict[str, Any] = {"seed": config.data_seed, "test_duration": config.test_duration}
    if config.n_traj is not None:
        settings["n_traj"] = config.n_traj
    for name in ("duration", "dt"):
        if getattr(config, name) is not None:
            settings[name] = getattr(config, name)
    if actuation is not None:
        settings["actuation"] = actuation
    return DataJob(scenario, settings)


def build_grid(config: ReproduceConfig) -> tuple[list[DataJob], list[ModelJob]]:
    """Every data set and every (data set × model × seed) job the tables need, without repeats."""
    train = {"steps": config.steps, "batch_size": config.batch_size, "val_every": config.val_every}
    polish = {"lbfgs_steps": config.lbfgs_steps} if config.lbfgs_steps else {}
    datasets: dict[str, DataJob] = {}
    jobs: dict[str, ModelJob] = {}

    def add(d: DataJob, model: str, ablation: str = "none") -> None:
        datasets.setdefault(d.id, d)
        for seed in range(config.seeds):
            extra = polish if model == "fhnn" else {}
            job = ModelJob(d, model, ablation, seed, {**train, **extra, "seed": seed})
            jobs.setdefault(job.id, job)

    for sc in config.main_scenarios:
        d = data_job(config, sc)
        for model in config.models:
            add(d, model)
        for ab in config.ablations:
            add(d, "fhnn", ab)
    for sc in config.scenario_table:
        add(data_job(config, sc), "fhnn")
    if config.identifiability:
        add(data_job(config, "steady_vortex", actuation="none"), "fhnn")
    return list(datasets.values()), list(jobs.values())
