"""The reproduction as a grid of independent jobs (docs/spec.md §6).

Two kinds of job:

- a **data job** simulates one data set (a scenario at the reproduction's data settings);
- a **model job** trains one model (FHNN, an ablation or a baseline) on one data set with one seed,
  then evaluates it (metrics at every horizon the tables and figures need, in both averagings,
  the first four test rollouts, and for FHNN the parameter and flow recovery).

Every job is identified by a hash of everything that determines its result: its specification
(for a model job the fully resolved model and training settings, defaults included), the data
set's specification, and the source code that computes it (:data:`DATA_SOURCES` for a data set,
:data:`MODEL_SOURCES` for a model job; :func:`~fhnn.runtime.source_digest`). A finished job is
recognised and skipped however the grid around it changed; a changed setting, default or line of
the code a job runs reruns that job, and a change elsewhere (the CLI, tables, figures, report)
reruns nothing.

Which jobs the tables need (``S`` = seeds):

- T1, T2, T3, T5 on each of ``main_scenarios``: every model of ``models`` and FHNN's ``ablations``;
- T4: FHNN on each of ``scenario_table`` (shared with the main scenarios where they coincide);
- T6: FHNN's recovery on the main scenarios, and on ``steady_vortex`` without actuation (the
  identifiability contrast), when ``identifiability`` is set.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import masses_are_gauge
from fhnn.data.simulate import SimulationConfig
from fhnn.errors import ConfigError
from fhnn.models.registry import MODELS
from fhnn.physics.scenarios import PAPER_SCENARIOS, SCENARIOS
from fhnn.runtime import source_digest
from fhnn.training.plans import DEFAULT_PLAN, PLANS, model_data_settings
from fhnn.training.run import RunConfig
from fhnn.training.trainer import TrainConfig

#: Horizons [s] every model is evaluated at: T1 (1–4, 8, 16), T2 (1, 5), T3 (30, 60, 120), T4/T5 (5).
HORIZONS = (1, 2, 3, 4, 5, 8, 16, 30, 60, 120)
#: FHNN's ablations (T5), from the registry.
ABLATIONS = tuple(MODELS["fhnn"].variants)


@frozen_config
class DataSettings(Config):
    """The simulated data sets of a reproduction.

    Attributes:
        n_traj: trajectories per data set (``None``: each scenario's default, docs/spec.md §3).
        duration: length of train and val trajectories [s] (``None``: the scenario's default).
        dt: sampling interval [s] (``None``: the scenario's default).
        test_duration: length of test trajectories [s]; at least the longest horizon (120 s).
        seed: seed of every simulated data set.
    """

    config_name = "reproduce.data"

    n_traj: int | None = None
    duration: float | None = None
    dt: float | None = None
    test_duration: float = 120.0
    seed: int = 0

    def validate(self) -> None:
        check_positive(self, "test_duration")
        check_nonnegative(self, "seed")
        if self.n_traj is not None and self.n_traj < 3:
            raise ConfigError(f"reproduce: n_traj must be >= 3 (one per split), got {self.n_traj}")
        for name in ("duration", "dt"):
            value = getattr(self, name)
            if value is not None and value <= 0:
                raise ConfigError(f"reproduce: {name} must be > 0, got {value}")


def _model_options() -> type[Config]:
    """``ModelOptions``: one field per registered model kind, holding that kind's configuration
    (``model.fhnn.width``, ``model.dhn.block``, …)."""
    namespace: dict[str, Any] = {
        "__annotations__": {name: kind.config for name, kind in MODELS.items()},
        "__doc__": "Per model kind, the configuration its reproduction jobs use.",
        "__module__": __name__,
        "config_name": "reproduce.model",
    }
    for name, kind in MODELS.items():
        namespace[name] = dataclasses.field(default_factory=kind.config)
    return frozen_config(type("ModelOptions", (Config,), namespace))


ModelOptions = _model_options()

#: Wall-clock budget [s] of every gradient-trained job's training (``train.max_time``).
JOB_SECONDS = 75.0
#: Adam steps of the reproduction (the default plan: 20,000).
JOB_ADAM_STEPS = 6000
#: Training pairs of the quasi-Newton phases in the reproduction (the default plan: 4,000).
JOB_LBFGS_PAIRS = 2000


def reproduction_train() -> TrainConfig:
    """The training of every gradient-trained job: the default plan (warm-up where a model has
    warm-up parameters, kept or discarded on its validation loss; Adam; L-BFGS polish; its loss
    terms) with :data:`JOB_ADAM_STEPS` Adam steps, :data:`JOB_LBFGS_PAIRS` quasi-Newton pairs and
    :data:`JOB_SECONDS` per job, the polish getting what the earlier phases leave
    (``train.max_time``)."""
    return PLANS[DEFAULT_PLAN].train.replace(
        steps=JOB_ADAM_STEPS, max_time=JOB_SECONDS, lbfgs_pairs=JOB_LBFGS_PAIRS
    )


def reproduction_models() -> Config:
    """Each model kind's configuration in the reproduction: its defaults with the default plan's
    model settings (FHNN width 32 and slow-window weights, ``slow_weight`` 1), so the ablations
    share FHNN's architecture. On each data set :func:`build_grid` then applies the model settings
    ``fhnn train`` applies for such data (:func:`~fhnn.training.plans.model_data_settings`: FHNN
    ``slow_weight`` 0 on noisy observations, constant added masses without known forcing)."""
    plan = PLANS[DEFAULT_PLAN]
    return ModelOptions.from_dict(
        {kind: MODELS[kind].config().replace(**plan.model.get(kind, {})).to_dict() for kind in MODELS}
    )


@frozen_config
class ReproduceConfig(Config):
    """What ``fhnn reproduce`` runs. Settings are addressed with dotted names (``seeds``,
    ``data.n_traj``, ``train.steps``, ``model.fhnn.width``); each field is documented below it.
    """

    config_name = "reproduce"

    seeds: int = 3
    """Training seeds per model, 0 … seeds − 1 (each table cell is the mean ± std over them)."""
    models: tuple[str, ...] = tuple(MODELS)
    """Models of T1/T2 (``fhnn`` plus baselines of the registry)."""
    ablations: tuple[str, ...] = ABLATIONS
    """FHNN ablations of T5."""
    main_scenarios: tuple[str, ...] = ("solid_body_vortex", "steady_vortex")
    """Scenarios of T1, T2, T3, T5 and the figures."""
    scenario_table: tuple[str, ...] = PAPER_SCENARIOS
    """Scenarios of T4."""
    identifiability: bool = True
    """Add ``steady_vortex`` without actuation to T6."""
    data: DataSettings = DataSettings()
    """The simulated data sets (:class:`DataSettings`)."""
    train: TrainConfig = dataclasses.field(default_factory=reproduction_train)
    """The training of every gradient-trained model — the same plan and wall-clock budget for all
    (:class:`~fhnn.training.train_config.TrainConfig`, default :func:`reproduction_train`; its seed is
    set per job)."""
    model: ModelOptions = dataclasses.field(default_factory=reproduction_models)  # type: ignore[valid-type]
    """Each model kind's configuration (``ModelOptions``, default :func:`reproduction_models`); on
    data sets with observation noise the settings such data call for replace the fields they name
    (FHNN ``slow_weight``)."""
    fast_compile: bool = False
    """Compile the jobs' programs for compilation speed rather than run speed (LLVM optimisation level
    0 in the worker processes), for runs whose jobs are short, where compilation is most of the time
    (the quick preset); with ``--workers 1`` the jobs then run in one worker process, not in this one
    (XLA reads its flags when a process first compiles). Results differ from the usual compilation's
    in their last bits (~1e-13 relative), so the setting is part of every job's key."""
    seeds_together: bool = False
    """Train each table cell's seeds (one model on one data set) as one task — the members of one
    ensemble, their Adam phases as one ``vmap``-ed program
    (:func:`fhnn.training.ensemble.train_members`) — instead of a job per seed. It pays where one
    program can fill the machine (a GPU), not on a 2-core CPU, where a job per seed keeps both cores
    busy, so it is off by default (measurements: design note ``docs/design/plans.md``). The vmapped
    sums change the last bits, so the setting is part of every grouped job's key."""

    def validate(self) -> None:
        check_positive(self, "seeds")
        if self.data.test_duration < max(HORIZONS):
            raise ConfigError(
                f"reproduce: test_duration must cover the longest horizon ({max(HORIZONS)} s), "
                f"got {self.data.test_duration} (data.test_duration)"
            )
        if self.train.seed != 0:
            raise ConfigError("reproduce: train.seed is set per job (0 … seeds − 1); set seeds instead")
        _check_names("models", self.models, MODELS)
        _check_names("ablations", self.ablations, ABLATIONS)
        _check_names("main_scenarios", self.main_scenarios, SCENARIOS)
        _check_names("scenario_table", self.scenario_table, SCENARIOS)
        if not (self.models or self.scenario_table):
            raise ConfigError("reproduce: nothing to run (models and scenario_table are both empty)")

    @classmethod
    def quick(cls, settings: dict[str, Any] | None = None) -> ReproduceConfig:
        """Small data sampled at 0.1 s, 80 Adam steps on the default plan's loss terms (no warm-up,
        no polish), one seed, the paper's models only, T1/T2/T3/T5 on
        ``solid_body_vortex`` only and no identifiability contrast: the whole report in a few
        minutes on 2 cores (every table and figure present and well-formed; the numbers are far
        from converged), its jobs compiled for compilation speed (``fast_compile``: most of a quick
        job is compilation); dotted-name ``settings`` change it further."""
        base = cls.from_dict(
            {
                "seeds": 1,
                # the plan's loss (derivative loss alone, no penalty): smaller programs, 81 s
                # against 91 s cold on the 2-core CPU (2026-11-25, two runs each)
                "train": {
                    "steps": 80,
                    "val_every": 40,
                    "warmup_steps": 0,
                    "lbfgs_steps": 0,
                    **_loss_terms(PLANS[DEFAULT_PLAN].train),
                },
                "data": {"n_traj": 20, "duration": 3.0, "dt": 0.1},
                "main_scenarios": ("solid_body_vortex",),
                "models": tuple(name for name, kind in MODELS.items() if kind.in_paper),
                "identifiability": False,
                "fast_compile": True,
            }
        )
        return base.with_settings(settings or {})


def _loss_terms(train: TrainConfig) -> dict[str, float]:
    """The loss-term weights of a training configuration, as settings."""
    return {k: getattr(train, k) for k in ("w_deriv", "w_step", "lambda_flow")}


def _check_names(what: str, names: tuple[str, ...], valid: Any) -> None:
    for name in names:
        if name not in valid:
            raise ConfigError(f"reproduce: unknown name {name!r} in {what}; valid: {', '.join(valid)}")
    if len(set(names)) != len(names):
        raise ConfigError(f"reproduce: {what} lists a name twice: {', '.join(names)}")


#: The package sources (relative to the package) a data set's bytes depend on.
DATA_SOURCES = ("physics", "data", "config.py", "errors.py", "files.py", "runtime.py")
#: The package sources a model job's result depends on: the data's, the models, training,
#: evaluation, and the job itself.
MODEL_SOURCES = (
    *DATA_SOURCES,
    "models",
    "training",
    "evaluation",
    "experiments/jobs.py",
    "experiments/grid.py",
)


def _digest(spec: dict[str, Any], sources: tuple[str, ...]) -> str:
    text = json.dumps({**spec, "source": source_digest(sources)}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class DataJob:
    """Simulate ``scenario`` with the simulation settings ``settings`` (SimulationConfig fields);
    ``fast_compile``: in workers compiled for compilation speed (:class:`ReproduceConfig`), whose
    results differ from the usual compilation's in the last bits (~1e-13 relative), so it is part
    of the key of the data set and of every model job on it."""

    scenario: str
    settings: dict[str, Any] = field(hash=False)
    fast_compile: bool = False

    @property
    def label(self) -> str:
        return self.scenario + ("_noact" if self.settings.get("actuation") == "none" else "")

    @property
    def noisy(self) -> bool:
        """Whether the data set's observations carry noise (the scenario's ``obs_noise`` > 0)."""
        return float(self.settings.get("obs_noise", SCENARIOS[self.scenario].defaults.obs_noise)) > 0

    @property
    def masses_are_gauge(self) -> bool:
        """Whether the data set's added masses are a free gauge (no known forcing; see
        :attr:`fhnn.data.dataset.Dataset.masses_are_gauge`), known before it is simulated."""
        scenario = SCENARIOS[self.scenario]()
        config = SimulationConfig.for_scenario(scenario, **self.settings)
        return masses_are_gauge(config.actuation != "none", scenario.body().to_dict())

    @property
    def spec(self) -> dict[str, Any]:
        spec = {"kind": "data", "scenario": self.scenario, "settings": self.settings}
        return {**spec, "fast_compile": True} if self.fast_compile else spec

    @property
    def id(self) -> str:
        return f"{self.label}-{_digest(self.spec, DATA_SOURCES)}"

    @property
    def filename(self) -> str:
        return f"{self.id}.h5"


@dataclass(frozen=True)
class ModelJob:
    """Train ``run`` (a model kind, FHNN ``ablation``, with ``seed``) on ``data``, then evaluate it;
    ``together``: as a member of its cell's ensemble (:attr:`ReproduceConfig.seeds_together`)."""

    data: DataJob
    model: str
    ablation: str
    seed: int
    run: RunConfig = field(hash=False)
    together: bool = False

    @property
    def cell(self) -> tuple[str, str, str]:
        """The table cell the job is a seed of: its data set, model and ablation."""
        return (self.data.id, self.model, self.ablation)

    @property
    def variant(self) -> str:
        """``fhnn``, an ablation's name, or a baseline's name."""
        return self.ablation if self.ablation != "none" else self.model

    @property
    def label(self) -> str:
        return f"{self.data.label}__{self.variant}__s{self.seed}"

    @property
    def spec(self) -> dict[str, Any]:
        """Everything that determines the job's result: the data set's specification and the
        fully resolved run configuration."""
        return {
            "kind": "model",
            "data": self.data.spec,
            "model": self.model,
            "ablation": self.ablation,
            "seed": self.seed,
            "model_config": self.run.model.to_dict(),  # type: ignore[union-attr]
            "train": self.run.train.to_dict(),
            "horizons": list(HORIZONS),
            **({"together": True} if self.together else {}),
        }

    @property
    def id(self) -> str:
        return f"{self.label}-{_digest(self.spec, MODEL_SOURCES)}"


def data_job(config: ReproduceConfig, scenario: str, *, actuation: str | None = None) -> DataJob:
    """The data set of ``scenario`` at the reproduction's settings."""
    d = config.data
    settings: dict[str, Any] = {"seed": d.seed, "test_duration": d.test_duration}
    for name in ("n_traj", "duration", "dt"):
        if getattr(d, name) is not None:
            settings[name] = getattr(d, name)
    if actuation is not None:
        settings["actuation"] = actuation
    return DataJob(scenario, settings, config.fast_compile)


def build_grid(config: ReproduceConfig) -> tuple[list[DataJob], list[ModelJob]]:
    """Every data set and every (data set × model × seed) job the tables need, without repeats."""
    datasets: dict[str, DataJob] = {}
    jobs: dict[str, ModelJob] = {}

    def add(d: DataJob, model: str, ablation: str = "none") -> None:
        datasets.setdefault(d.id, d)
        model_config = getattr(config.model, model)
        # the model settings fhnn train applies for these data (plans.data_settings)
        implied = model_data_settings(model, noisy=d.noisy, masses_are_gauge=d.masses_are_gauge)
        model_config = model_config.replace(**implied)
        if ablation != "none":
            model_config = model_config.replace(ablation=ablation)
        for seed in range(config.seeds):
            run = RunConfig(kind=model, model=model_config, train=config.train.replace(seed=seed))
            job = ModelJob(d, model, ablation, seed, run, config.seeds_together and config.seeds > 1)
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
