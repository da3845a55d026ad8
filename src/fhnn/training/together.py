"""Members of an ensemble trained together: their Adam phases as one ``vmap``-ed program."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import equinox as eqx
import jax

from fhnn.training.adam import _adam_phase

if TYPE_CHECKING:
    from fhnn.training.trainer import Trainer, TrainState


def can_run_together(trainers: list[Trainer], states: list[TrainState]) -> bool:
    """Whether :func:`run_together` can train these members' Adam phases as one program: at least
    two, configurations equal but for the seed, every member at the same Adam step before the
    end, models of one structure, and the same training windows."""
    if len(trainers) < 2:
        return False
    first, state = trainers[0], states[0]
    configs = {t.config.replace(seed=0) for t in trainers}
    steps = {s.step for s in states}
    shapes = {str(jax.tree.structure(eqx.filter(s.model, eqx.is_array))) for s in states}
    same_data = all(len(t.train_pairs) == len(first.train_pairs) for t in trainers)
    return (
        len(configs) == 1
        and steps == {state.step}
        and state.step < first.config.steps
        and len(shapes) == 1
        and same_data
    )


def run_together(
    trainers: list[Trainer],
    states: list[TrainState],
    *,
    callbacks: list[Callable[[TrainState, dict[str, float]], None] | None],
    checkpoints: list[Callable[[TrainState], None] | None],
    checkpoint_seconds: float = 60.0,
) -> list[TrainState]:
    """The Adam phase of several members (runs differing only in their seed, see :func:`can_run_together`) as
    one ``vmap``-ed program per chunk of steps (:func:`adam_chunk`, stacked), each member otherwise as
    :meth:`Trainer.run` trains it alone: the same minibatches, validations, records, guards and
    checkpoints (``callbacks[j]`` and ``checkpoints[j]`` for member ``j``). A member whose guard or budget
    ends its Adam phase leaves the group; the rest go on as a smaller one (one more compilation). Under a
    time budget each member is charged its share of the group's time (the wall time over the members
    training), so a member's budget buys the steps it would alone. Against sequential members this trades
    nothing but the order of floating-point sums; for the throughput it buys see
    ``docs/design/data/training_speed*.txt``."""
    _adam_phase(trainers, states, callbacks, checkpoints, trainers[0].config.steps, checkpoint_seconds)
    return states
