"""The wall-clock budget of one command's training (``train.max_time``), what a budget cut leaves
to do, and what a run's phases ran.

A :class:`Budget` counts from the start of the command that trains (compilation, the warm-up,
every member of an ensemble and their checkpoints included) to ``start + max_time``. The phases
before an L-BFGS polish or a whole-track fit end at :data:`PRE_POLISH_SHARE` of it; the final
phases end at the budget. Members of an ensemble that train one after another each get an equal
share of what is left (:meth:`Budget.turn`). A phase cut by the budget marks its last record
``"budget": True``; the next command on the run continues from there (:func:`rewind_cut`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from fhnn.training.train_config import TrainConfig
    from fhnn.training.trainer import TrainState

#: Share of the budget that the phases before an L-BFGS polish or a whole-track fit may use (the
#: final phases get the rest: an iteration on the whole model costs ~25 Adam steps, and it is what
#: brings the loss below Adam's noise floor).
PRE_POLISH_SHARE = 0.5

#: The phases that end at the budget itself; the others end at :data:`PRE_POLISH_SHARE` of it.
FINAL_PHASES = ("lbfgs", "tracks")

#: A history record's ``phase`` (absent: Adam) and how a summary names it.
PHASE_LABELS = {None: "Adam", "warmup": "warm-up", "lbfgs": "L-BFGS polish", "tracks": "whole-track fit"}


class Budget:
    """A command's training budget: ``seconds`` of wall clock from ``start``.

    Args:
        seconds: the budget [s]; 0 or less: none (every deadline infinite).
        final_phases: whether a polish or a whole-track fit follows the first phases (they then
            end at :data:`PRE_POLISH_SHARE` of the budget).
        start: ``time.monotonic()`` when the command began (default: now).
        whole: the command's budget [s] where this is a member's share of it (:meth:`share`).
    """

    def __init__(
        self, seconds: float, *, final_phases: bool, start: float | None = None, whole: float | None = None
    ) -> None:
        self.seconds = float(seconds)
        self.whole = self.seconds if whole is None else float(whole)
        self.start = time.monotonic() if start is None else start
        self.limited = self.seconds > 0
        self.end = self.start + self.seconds if self.limited else math.inf
        self.final_phases = final_phases
        share = PRE_POLISH_SHARE if final_phases else 1.0
        #: When the phases before the final ones end.
        self.first_end = self.start + share * self.seconds if self.limited else math.inf
        #: The end of the current member's turn (:meth:`turn`), infinite outside one.
        self.cap = math.inf

    @classmethod
    def of(cls, config: TrainConfig, start: float | None = None) -> Budget:
        """The budget ``config.max_time`` of a training with ``config``'s phases."""
        final = config.lbfgs_steps > 0 or config.track_steps > 0
        return cls(config.max_time, final_phases=final, start=start)

    def deadline(self, phase: str) -> float:
        """When ``phase`` ("warmup", "adam", "lbfgs" or "tracks") must end (``time.monotonic()``)."""
        return min(self.end if phase in FINAL_PHASES else self.first_end, self.cap)

    def spent(self) -> float:
        """Seconds since the start."""
        return time.monotonic() - self.start

    def sink(self) -> None:
        """A discarded warm-up: the first phases end at :data:`PRE_POLISH_SHARE` of what is left."""
        if self.limited and self.final_phases:
            now = time.monotonic()
            self.first_end = now + PRE_POLISH_SHARE * max(0.0, self.end - now)

    @contextmanager
    def turn(self, phase: str, members_left: int) -> Iterator[None]:
        """One member's ``phase`` among ``members_left`` that still run it one after another: it
        ends at its equal share of the time left to the phase's deadline."""
        if not self.limited or members_left <= 1:
            yield
            return
        now = time.monotonic()
        target = self.end if phase in FINAL_PHASES else self.first_end
        self.cap = now + max(0.0, target - now) / members_left
        try:
            yield
        finally:
            self.cap = math.inf

    def share(self, members_left: int) -> Budget:
        """A budget of its own for the next of ``members_left`` members that train one after
        another: an equal share of the time left, split between its phases as this one is."""
        if not self.limited:
            return self
        left = max(1e-9, self.end - time.monotonic()) / max(1, members_left)
        return Budget(left, final_phases=self.final_phases, whole=self.whole)

    def describe(self, phase: str) -> str:
        """How the budget reads in a cut's message (``train.max_time=60 s, 50% of it before …``)."""
        text = f"train.max_time={self.whole:g} s"
        if self.cap < math.inf or self.whole != self.seconds:
            text += ", this member's share of it"
        if phase not in FINAL_PHASES and self.final_phases:
            text += f", {PRE_POLISH_SHARE:.0%} of it before the polish"
        return text


def phase_counts(history: list[dict[str, Any]], config: TrainConfig) -> list[tuple[str, int, int]]:
    """What each planned phase of ``config`` ran, from a run's ``history``: ``(label, done,
    planned)`` for Adam (steps), the L-BFGS polish and the whole-track fit (iterations); a phase
    the plan does not have is left out, and Adam after a kept warm-up counts 0."""
    adam = [r["step"] for r in history if "phase" not in r]
    lbfgs = [r["step"] - config.steps for r in history if r.get("phase") == "lbfgs"]
    tracks = [r["step"] - config.steps - config.lbfgs_steps for r in history if r.get("phase") == "tracks"]
    out = [("Adam", max(adam, default=0), config.steps)]
    if config.lbfgs_steps:
        out.append(("L-BFGS polish", lbfgs[-1] if lbfgs else 0, config.lbfgs_steps))
    if config.track_steps:
        out.append(("whole-track fit", tracks[-1] if tracks else 0, config.track_steps))
    return out


def ran_text(history: list[dict[str, Any]], config: TrainConfig) -> str:
    """``Adam 1,001 of 4,000 steps, L-BFGS polish 20 of 10,000 iterations, …``: what ran."""
    parts = []
    for label, done, planned in phase_counts(history, config):
        unit = "steps" if label == "Adam" else "iterations"
        parts.append(f"{label} {done:,} of {planned:,} {unit}")
    return ", ".join(parts)


def pending_cut(state: TrainState) -> dict[str, Any] | None:
    """The first record of ``state.history`` where the time budget cut a phase and no later
    command has continued from (``"budget": True``), else ``None``. A warm-up cut is not
    continued: the warm-up decided on what it had."""
    return next(
        (r for r in state.history if r.get("budget") is True and r.get("phase") != "warmup"),
        None,
    )


def rewind_cut(state: TrainState, config: TrainConfig) -> str | None:
    """Set ``state`` back to where the time budget first cut a phase, so that training continues
    there: Adam from its step with its optimiser state (from the best model so far), the polish
    with its iterations left (from the best model), the whole-track fit with its iterations left.
    The budget's words leave ``state.stopped``; a guard's stay. Returns what continues (``None``:
    no cut to continue)."""
    cut = pending_cut(state)
    if cut is None:
        return None
    for record in state.history:
        if record.get("budget") is True:
            record["budget"] = "continued"
    phase = cut.get("phase")
    state.step = int(cut["step"])
    state.model = state.best_model
    if state.stopped is not None:
        kept = [part for part in state.stopped.split("; ") if "the time budget" not in part]
        state.stopped = "; ".join(kept) or None
    # the phases count on in one step counter: Adam, then the polish, then the whole-track fit
    planned, offset = {
        None: (config.steps, 0),
        "lbfgs": (config.lbfgs_steps, config.steps),
        "tracks": (config.track_steps, config.steps + config.lbfgs_steps),
    }[phase]
    done = state.step - offset
    unit = "step" if phase is None else "iteration"
    where = f"{unit} {done:,} of {planned:,}"
    return f"continues the {PHASE_LABELS[phase]} from {where}, where the time budget cut it"
