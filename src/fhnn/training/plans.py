"""Named training plans: typed presets of :class:`~fhnn.training.trainer.TrainConfig`.

A plan fixes the phases of a run (quasi-Newton warm-up, Adam, quasi-Newton polish) and their
lengths; ``fhnn train --plan NAME`` starts from it and ``--set train.NAME=VALUE`` changes any
field. The measurements behind each plan are in its summary (2-core CPU, one seed, default data
sets of the scenario named).
"""

from __future__ import annotations

from dataclasses import dataclass

from fhnn.errors import ConfigError
from fhnn.training.trainer import TrainConfig


@dataclass(frozen=True)
class TrainingPlan:
    """A named training configuration.

    Attributes:
        name: what ``--plan`` takes.
        summary: what the plan does and what it was measured to reach.
        train: the training configuration it stands for.
    """

    name: str
    summary: str
    train: TrainConfig


PLANS: dict[str, TrainingPlan] = {
    p.name: p
    for p in (
        TrainingPlan(
            "adam", "20,000 Adam steps, piecewise-constant rate (the paper's optimiser)", TrainConfig()
        ),
        TrainingPlan(
            "warmup-polish",
            "L-BFGS warm-up of the linear flow and coefficients (400), then L-BFGS on everything "
            "(400); solid_body_vortex: RMSE(pos) 7.4e-6 / 3.3e-5 / 1.4e-3 m at 1 / 5 / 60 s in ~300 s",
            TrainConfig(steps=0, warmup_steps=400, lbfgs_steps=400, lbfgs_pairs=8000),
        ),
        TrainingPlan(
            "adam-polish",
            "12,000 Adam steps, then L-BFGS (700) on 8,000 pairs; steady_vortex (actuated): "
            "RMSE(pos) 5.0e-5 m at 5 s, masses and c_l within 0.6 %, in ~500 s",
            TrainConfig(steps=12000, lbfgs_steps=700, lbfgs_pairs=8000),
        ),
    )
}


def get_plan(name: str) -> TrainingPlan:
    """The plan ``name``; an unknown name is a :class:`ConfigError` listing the plans."""
    if name not in PLANS:
        raise ConfigError(f"unknown training plan {name!r}; available: {', '.join(PLANS)}")
    return PLANS[name]


__all__ = ["PLANS", "TrainingPlan", "get_plan"]
