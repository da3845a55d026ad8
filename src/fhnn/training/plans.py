"""Named training plans: typed presets of :class:`~fhnn.training.train_config.TrainConfig`.

A plan fixes the phases of a run (quasi-Newton warm-up, Adam, quasi-Newton polish) and their
lengths; ``fhnn train --plan NAME`` starts from it and ``--set train.NAME=VALUE`` changes any
field. The measurements behind each plan are in its summary (2-core CPU, one seed, default data
sets of the scenario named).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fhnn.data.dataset import Dataset
from fhnn.data.observation import start_errors
from fhnn.errors import ConfigError
from fhnn.models.registry import MODELS
from fhnn.training.trainer import TrainConfig


@dataclass(frozen=True)
class TrainingPlan:
    """A named training configuration.

    Attributes:
        name: what ``--plan`` takes.
        summary: what the plan does and what it reaches.
        train: the training configuration it stands for.
        model: model settings per model kind that go with the plan (e.g. the FHNN's width),
            applied to runs of that kind only.
    """

    name: str
    summary: str
    train: TrainConfig
    model: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)

    def settings(self, kind: str) -> dict[str, Any]:
        """The plan as dotted settings for a run of ``kind``: every ``train.*`` field and the
        plan's ``model.*`` settings for that kind — what ``fhnn train --plan`` starts from; a
        ``--set`` of the same name wins."""
        MODELS[kind]  # an unknown kind is refused
        out = {f"train.{k}": v for k, v in self.train.to_dict().items()}
        out.update({f"model.{k}": v for k, v in self.model_settings(kind).items()})
        return out

    def model_settings(self, kind: str) -> dict[str, Any]:
        """The plan's model settings for a run of ``kind`` (field name → value)."""
        return dict(self.model.get(kind, {}))


#: The paper's optimiser and loss where they differ from the defaults: Adam alone, the one-step
#: loss beside the derivative loss, the annealed flow penalty (``adam`` and the plans built on it).
PAPER_TRAIN = TrainConfig(
    warmup_steps=0, warmup_accept=0.0, lbfgs_steps=0, lbfgs_pairs=8192, w_step=1.0, lambda_flow=1e-6
)

#: The paper's FHNN where it differs from the defaults: width 64, every window alike.
PAPER_FHNN = {"width": 64, "slow_weight": 0.0}

#: The plan ``fhnn train`` and :func:`fhnn.train` use when none is named.
DEFAULT_PLAN = "auto"

PLANS: dict[str, TrainingPlan] = {
    p.name: p
    for p in (
        TrainingPlan(
            "auto",
            "the default: the configuration defaults (TrainConfig(), FHNNConfig()). FHNN width 32; "
            "L-BFGS warm-up of the linear flow and coefficients (400); if its validation loss is "
            "<= 1e-6 the warm-up is kept and L-BFGS polishes everything (the warmup-polish route), "
            "otherwise it is discarded and 20,000 Adam steps and the polish (10,000) follow from the "
            "initial model (the adam-polish route); models without a warm-up part take the second "
            "route; 4,000 pairs. Where derivatives are measured the loss is the derivative loss "
            "alone (no one-step loss) and there is no flow penalty; on noise-free observations each "
            "FHNN window is weighted by its slowness (slow_weight 1)",
            TrainConfig(),
        ),
        TrainingPlan(
            "adam",
            "20,000 Adam steps, piecewise-constant rate (the paper's optimiser, loss and FHNN width 64)",
            PAPER_TRAIN,
            model={"fhnn": PAPER_FHNN},
        ),
        TrainingPlan(
            "warmup-polish",
            "FHNN width 32; L-BFGS warm-up of the linear flow and coefficients (400), then L-BFGS on "
            "everything (400); solid_body_vortex: RMSE(pos) 6.7e-6 / 1.9e-5 / 3.4e-3 m at 1 / 5 / 60 s "
            "in ~100 s",
            PAPER_TRAIN.replace(steps=0, warmup_steps=400, lbfgs_steps=400, lbfgs_pairs=8000),
            # chosen on the validation loss: width 32 reached 1.34e-9 in 90 s against 7.8e-9 in 158 s
            # at width 64, and on a second data seed 1.56e-9 in 87 s against 3.1e-9 in 154 s
            model={"fhnn": {**PAPER_FHNN, "width": 32}},
        ),
        TrainingPlan(
            "adam-polish",
            "12,000 Adam steps, then L-BFGS (700) on 8,000 pairs; steady_vortex (actuated): "
            "RMSE(pos) 5.1e-5 m at 5 s, masses within 0.55 % and c_l within 0.19 %, in ~340 s",
            PAPER_TRAIN.replace(steps=12000, lbfgs_steps=700, lbfgs_pairs=8000),
            model={"fhnn": PAPER_FHNN},
        ),
    )
}

#: The plan a new run starts from when none is named and the data's velocities were estimated
#: (:func:`default_settings`); :func:`data_settings` then sets the multi-step loss.
ESTIMATED_VELOCITY_PLAN = "adam"


#: Multi-step window [samples] of the loss on positions used when velocities were estimated.
ESTIMATED_VELOCITY_SHOOT = 40

#: Levenberg–Marquardt iterations of the whole-track fit after Adam where velocities were
#: estimated (``train.track_steps``; see :func:`data_settings`): the fewest of 2–20 whose
#: validation forecasts and validation-track misfit were within 1 % and 5 % of 20's on the
#: own-data choosing seeds (``benchmarks/track_iterations.py``).
ESTIMATED_VELOCITY_TRACK_STEPS = 15

#: Learning-rate multiplier of the constant linear drag with the multi-step loss
#: (``train.lr_c_l``; see :func:`data_settings`).
ESTIMATED_VELOCITY_LR_C_L = 10.0


def data_settings(dataset: Dataset, kind: str = "fhnn") -> dict[str, Any]:
    """Training settings that a data set's recorded fields call for (``fhnn train`` applies them
    above a plan and below any setting given), for a model of ``kind``:

    - FHNN without known forcing (:attr:`~fhnn.data.dataset.Dataset.masses_are_gauge`): the added
      masses held to two constants (``model.added_mass="constant"``): only ``c / (M + m_a)`` is
      determined by such data.
    - derivatives estimated, not recorded: no derivative loss (``train.w_deriv=0``), the one-step
      loss on (``train.w_step=1``).
    - velocities estimated too: the multi-step loss on positions over windows of
      :data:`ESTIMATED_VELOCITY_SHOOT` samples in batches of 32, no one-step loss, 4,000 Adam
      steps; the constant linear drag stepped 10× faster (``train.lr_c_l``); each window's
      residuals weighed by their covariance under its start errors (``train.shoot_noise``); and
      after Adam the whole-track fit of :data:`ESTIMATED_VELOCITY_TRACK_STEPS` iterations
      (``train.track_steps``) with its forecast guard.

    Why each: the design note ``docs/design/plans.md``.

    Args:
        dataset: the data set to be trained on.
        kind: the model kind (settings for FHNN; the losses for every kind).

    Returns:
        Dotted settings (``{"train.w_deriv": 0.0, ...}``); empty for noise-free data with
        recorded velocities and derivatives.
    """
    model = model_data_settings(kind, noisy=is_noisy(dataset), masses_are_gauge=dataset.masses_are_gauge)
    out: dict[str, Any] = {f"model.{k}": v for k, v in model.items()}
    if "derivatives" not in dataset.measured:
        out["train.w_deriv"] = 0.0
        out["train.w_step"] = 1.0
    if "velocities" not in dataset.measured:
        out.update(
            {
                "train.shoot": ESTIMATED_VELOCITY_SHOOT,
                "train.w_step": 0.0,
                "train.batch_size": 32,
                "train.steps": 4000,
                # c_l steps 10x faster: at the plain rate it stays near its initial value
                "train.lr_c_l": ESTIMATED_VELOCITY_LR_C_L,
                # quasi-Newton on 8,000 windows of 40 samples costs 40× a one-step iteration
                "train.warmup_steps": 0,
                "train.lbfgs_steps": 0,
                # the windows' residuals weighed by their covariance under the start errors
                # (three significant digits: estimates, said so in fhnn train's message)
                "train.shoot_noise": tuple(float(f"{v:.3g}") for v in start_errors(dataset)),
                # then every training track at once, from fitted start states, where the split
                # of the drag between c_l and c_q is decided
                "train.track_steps": ESTIMATED_VELOCITY_TRACK_STEPS,
            }
        )
    return out


def default_settings(dataset: Dataset, kind: str = "fhnn") -> dict[str, Any]:
    """The plan settings a new run of ``kind`` on ``dataset`` starts from when no plan is named
    (``fhnn train`` without ``--plan``, :func:`fhnn.train` without one): :data:`DEFAULT_PLAN`'s,
    or :data:`ESTIMATED_VELOCITY_PLAN`'s for data whose velocities were estimated."""
    name = ESTIMATED_VELOCITY_PLAN if "velocities" not in dataset.measured else DEFAULT_PLAN
    return PLANS[name].settings(kind)


def is_noisy(dataset: Dataset) -> bool:
    """Whether ``dataset``'s observations carry noise (``obs_noise > 0``): a simulation with
    observation noise or an imported table (whose noise is estimated, never zero)."""
    return dataset.obs_noise > 0


def noisy_model_settings(kind: str) -> dict[str, Any]:
    """Model settings (field → value) that observations with noise call for: FHNN windows not
    weighted by their slowness (``slow_weight`` 0). On ``noisy_flow`` the weighting was worse
    than none (m_ay 0.33 → 2.28 %, c_l 2.11 → 4.09 % off on a second job seed), while on the
    noise-free data sets it settled the drag split (``docs/design/data/slow_weight.txt``)."""
    return {"slow_weight": 0.0} if kind == "fhnn" else {}


def model_data_settings(kind: str, *, noisy: bool, masses_are_gauge: bool) -> dict[str, Any]:
    """The model settings (field → value) of :func:`data_settings`, from the data's traits:
    :func:`noisy_model_settings` for noisy observations, and for FHNN on data whose added masses
    are a gauge (:attr:`~fhnn.data.dataset.Dataset.masses_are_gauge`) the masses held constant.
    The reproduction's grid applies this before its data sets exist."""
    out = dict(noisy_model_settings(kind)) if noisy else {}
    if kind == "fhnn" and masses_are_gauge:
        out["added_mass"] = "constant"
    return out


def get_plan(name: str) -> TrainingPlan:
    """The plan ``name``; an unknown name is a :class:`ConfigError` listing the plans."""
    if name not in PLANS:
        raise ConfigError(f"unknown training plan {name!r}; available: {', '.join(PLANS)}")
    return PLANS[name]


__all__ = [
    "DEFAULT_PLAN",
    "ESTIMATED_VELOCITY_LR_C_L",
    "ESTIMATED_VELOCITY_PLAN",
    "ESTIMATED_VELOCITY_SHOOT",
    "PAPER_FHNN",
    "PAPER_TRAIN",
    "PLANS",
    "TrainingPlan",
    "data_settings",
    "default_settings",
    "get_plan",
    "is_noisy",
    "model_data_settings",
    "noisy_model_settings",
]
