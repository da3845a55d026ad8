"""Training of any :class:`~fhnn.models.base.AbstractModel` on a data set (docs/spec.md §5).

Loss ``L = w_deriv L_deriv + w_step L_step + λ_flow(step) L_flow``:

``L_deriv`` and ``L_step`` compare ``f(s, t, F(t))`` with the stored derivatives and one RK4 step
with the next observed state, per component scaled by the training set's spread
(:meth:`~fhnn.models.base.AbstractModel.loss_terms`); ``L_flow`` is the model's regularisation,
its weight annealed linearly to 0 over the first ``flow_anneal`` fraction of the steps.

Four phases:

1. Warm-up (``warmup_steps`` quasi-Newton iterations; only for models whose
   :meth:`~fhnn.models.base.AbstractModel.warmup` names a part): the part is fitted full-batch
   first. FHNN with a linear far field fits its linear flow and coefficient net this way before
   the stream MLP joins, so the MLP learns only what a linear flow cannot explain.
2. Adam with a piecewise-constant learning rate (×``lr_decay`` at each fraction in
   ``lr_boundaries``), minibatches drawn from ``jax.random.fold_in(key, step)`` so that a resumed
   run draws the same batches as an uninterrupted one. Once the penalty's weight is zero a step
   without it runs (see :meth:`TrainConfig.regularizes`).
3. Polish (``lbfgs_steps`` quasi-Newton iterations, all parameters) from the best model so far: in
   float64 it lowers the loss far below Adam's noise floor.
4. Whole-track fit (``track_steps`` Levenberg–Marquardt iterations, :mod:`fhnn.training.tracks`)
   from the best model so far: every training track at once from a fitted start state, on the
   parameters the model names; it ends at its last iterate that forecasts the validation tracks
   (from an origin every 2 s, 1 s of history, 5 s ahead) no worse than the phase's start.

The quasi-Newton phases run on a fixed, seeded subset of ``lbfgs_pairs`` windows (data terms
only), keeping ``lbfgs_memory`` curvature pairs; a run interrupted inside one restarts it.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree

from fhnn.data.dataset import Split
from fhnn.data.windows import LossScales, Windows
from fhnn.executables import StoredProgram
from fhnn.models.base import AbstractModel
from fhnn.training.adam import ADAM_CHUNK, AdamSettings, _adam_phase, adam_chunk, adam_step
from fhnn.training.budget import Budget
from fhnn.training.losses import _validation_terms, data_loss, loss_terms
from fhnn.training.quasi_newton import quasi_newton_objective, quasi_newton_step, strong_types
from fhnn.training.sampling import bootstrap_weights, draw_batch
from fhnn.training.tracks import ForecastScore, TrackFit, fitted_pieces, track_pieces
from fhnn.training.train_config import (
    PENALTY_FREE_MIN_STEPS,
    QUASI_NEWTON_FIELDS,
    SHOOT_DRIFTS,
    TrainConfig,
)

Array = jax.Array

__all__ = [  # the names other modules import from here (their definitions moved beside it)
    "ADAM_CHUNK",
    "PENALTY_FREE_MIN_STEPS",
    "QUASI_NEWTON_FIELDS",
    "SHOOT_DRIFTS",
    "AdamSettings",
    "TrainConfig",
    "TrainState",
    "Trainer",
    "adam_chunk",
    "adam_step",
    "bootstrap_weights",
    "data_loss",
    "draw_batch",
    "loss_terms",
    "quasi_newton_objective",
    "quasi_newton_step",
    "stop_reason",
    "strong_types",
]


#: A warm-up is abandoned (and discarded) at a record whose validation loss is above this many
#: times ``warmup_accept``: more than a warm-up was seen to fall in the rest of its iterations
#: (``solid_body_vortex``: 230× from iteration 40 to 400; ``steady_vortex`` stays at 0.13 from
#: iteration 40 on, ``time_varying_vortex`` at 0.17).
WARMUP_GIVE_UP = 1e4


@dataclass
class TrainState:
    """Everything needed to continue training: model, optimiser state, step, best model, history,
    the Adam steps skipped (non-finite loss or gradient) since the last history record, and why
    training stopped early (``None``: it did not; see :meth:`Trainer.run`)."""

    model: AbstractModel
    opt_state: Any
    step: int
    best_model: AbstractModel
    best_val: float
    history: list[dict[str, float]]
    skipped: float = 0.0
    stopped: str | None = None

    def add_stop(self, why: str) -> None:
        """Record one more reason training stopped early (after any before it)."""
        self.stopped = f"{self.stopped}; {why}" if self.stopped else why


def stop_reason(history: list[dict[str, Any]], config: TrainConfig) -> str | None:
    """Why Adam must stop after the last record of ``history`` (``None``: it goes on): every step
    since the previous record was skipped (a non-finite loss or gradient everywhere: the model can
    no longer move), or the validation loss rose at ``config.stop_rising`` validations in a row."""
    adam = [r for r in history if "phase" not in r]
    if not adam:
        return None
    last = adam[-1]
    previous = adam[-2]["step"] if len(adam) > 1 else 0
    if last.get("skipped_steps", 0.0) >= last["step"] - previous > 0:
        return f"every Adam step from {previous} to {last['step']} was skipped (non-finite loss or gradient)"
    n = config.stop_rising
    vals = [r["val_total"] for r in adam[-(n + 1) :]]
    if n and len(vals) == n + 1 and all(b > a for a, b in itertools.pairwise(vals)):
        steps = f"steps {adam[-n - 1]['step']}–{last['step']}"
        return f"the validation loss rose at {n} validations in a row ({steps})"
    return None


class Trainer:
    """Trains a model on the train split, validating on the val split."""

    def __init__(
        self,
        config: TrainConfig,
        train: Split,
        val: Split,
        *,
        window: int = 2,
        on_step: Callable[[str, int], None] | None = None,
        budget: Budget | None = None,
    ) -> None:
        """``on_step(phase, step)`` (optional) is told of progress between records, after every
        quasi-Newton step and every chunk of Adam steps (:func:`adam_chunk_end`; a cheap call: a
        progress bar throttles its own redrawing); phase is "warmup", "adam" or "lbfgs", step
        counts as in the history. ``budget``: the command's time budget, shared by the members
        of an ensemble (default: ``config.max_time`` from now)."""
        self.config = config
        self._on_step = on_step
        #: The time budget (:class:`~fhnn.training.budget.Budget`; see :meth:`deadline`).
        self.budget = budget if budget is not None else Budget.of(config)
        #: The compiled programs by name (executables kept on disk: :mod:`fhnn.executables`).
        self._programs: dict[str, StoredProgram] = {}
        #: The training and validation splits (the whole-track fit reads their tracks).
        self.train_split, self.val_split = train, val
        self.train_pairs = Windows.of(train, window, skip=config.first_start)
        #: Each training window's weight ``(P,)`` under ``config.bootstrap`` (its trajectory's
        #: weight, :func:`bootstrap_weights`), else None: every window counts once.
        self.window_weights = (
            bootstrap_weights(self.train_pairs.traj, train.n_traj, config.seed) if config.bootstrap else None
        )
        val_pairs = Windows.of(val, window, skip=config.first_start)
        if len(val_pairs) > config.val_pairs:
            idx = np.random.default_rng(config.seed).choice(len(val_pairs), config.val_pairs, replace=False)
            val_pairs = val_pairs.subset(np.sort(idx))
        self.val_pairs = val_pairs
        sc = LossScales.of(self.train_pairs)
        self.scales = (jnp.asarray(sc.deriv), jnp.asarray(sc.step))
        self.optimizer = self.optimizer_for(config)
        self._train = self.batch(self.train_pairs)
        # a fixed key for the stochastic parts of a model's objective (DHN's denoising) on validation
        self._val = self.batch(self.val_pairs, jax.random.PRNGKey(config.seed + 3))
        self._key = jax.random.PRNGKey(config.seed + 1)

    def batch(self, windows: Windows, key: Array | None = None) -> dict[str, Array]:
        """The arrays a model's loss reads from ``windows`` (:meth:`Windows.as_jax`), with their
        start-error variances (``TrainConfig.start_variance``) and, when given, ``key`` for the
        stochastic parts of an objective."""
        out = {**windows.as_jax(), **self.config.start_variance(len(windows))}
        return out if key is None else {**out, "key": key}

    def deadline(self, phase: str) -> float:
        """When ``phase`` ("warmup", "adam", "lbfgs" or "tracks") must end under the time budget
        (``time.monotonic()`` seconds; infinite without one): :meth:`Budget.deadline`."""
        return self.budget.deadline(phase)

    def _program(
        self, name: str, program: Callable[..., Any], *args: Any, donate: tuple[int, ...] = ()
    ) -> Any:
        """``program(*args)``, compiled once per ``name`` in this trainer (and kept on disk:
        :class:`~fhnn.executables.StoredProgram`). The arrays of the arguments at positions
        ``donate`` are given to the program's outputs: the caller must not use them again."""
        stored = self._programs.get(name)
        if stored is None:
            stored = self._programs[name] = StoredProgram(program, donate=donate)
        return jax.block_until_ready(stored(*args))  # timed work is done work

    def _over_budget(self, phase: str, step: int, of: int, what: str, ahead: float = 0.0) -> str | None:
        """The ``stopped`` text when ``phase`` has run past its :meth:`deadline`, or would with
        ``ahead`` seconds more (the next step's expected cost), else ``None``."""
        if time.monotonic() + ahead < self.deadline(phase):
            return None
        unit = "step" if phase == "adam" else "iteration"
        return (
            f"{what} stopped at {unit} {step} of {of}: the time budget "
            f"({self.budget.describe(phase)}) ran out after {self.budget.spent():.0f} s"
        )

    @property
    def total_steps(self) -> int:
        """Adam steps plus polish and whole-track iterations."""
        return self.config.steps + self.config.lbfgs_steps + self.config.track_steps

    def warmup(
        self, state: TrainState, callback: Callable[[TrainState, dict[str, float]], None] | None = None
    ) -> TrainState:
        """Quasi-Newton on the model's warm-up parameters; afterwards the model, the best model and
        a fresh Adam state start from the result. No-op for a model without a warm-up part."""
        parts = state.model.warmup()
        if parts is None or self.config.warmup_steps == 0:
            return state
        part, restore = parts
        initial, accept = state.model, self.config.warmup_accept
        hopeless = None
        if accept > 0:  # a warm-up that cannot reach the threshold is not finished

            def hopeless(record: dict[str, Any]) -> bool:
                return not record["val_total"] <= WARMUP_GIVE_UP * accept

        state = self._quasi_newton(
            state, part, self.config.warmup_steps, "warmup", callback, restore, give_up=hopeless
        )
        last = state.history[-1]
        if accept > 0 and not last["val_total"] <= accept:  # a NaN loss is discarded too
            last["warmup"] = "discarded"
            state.model, state.best_model, state.best_val = initial, initial, np.inf
            self.budget.sink()
        else:
            state.best_model, state.best_val = state.model, last["val_total"]
            if accept > 0:
                last["warmup"] = "kept"
                state.step = self.config.steps  # Adam skipped: the polish follows
        state.opt_state = self.optimizer.init(eqx.filter(state.model, eqx.is_array))
        return state

    def polish(
        self, state: TrainState, callback: Callable[[TrainState, dict[str, float]], None] | None = None
    ) -> TrainState:
        """Quasi-Newton on all parameters from the best model so far, for the iterations left
        (all of them from the end of Adam; fewer where a time budget cut the polish before:
        :func:`~fhnn.training.budget.rewind_cut`)."""
        done = max(0, state.step - self.config.steps)
        left = self.config.lbfgs_steps - done
        return self._quasi_newton(state, state.best_model, left, "lbfgs", callback, offset=done)

    def track_fit(
        self, state: TrainState, callback: Callable[[TrainState, dict[str, float]], None] | None = None
    ) -> TrainState:
        """The whole-track fit: ``track_steps`` Levenberg–Marquardt iterations on every training
        track (:class:`~fhnn.training.tracks.TrackFit`; under ``bootstrap`` each track weighted as
        its windows are) from the best model so far; the last ``track_whole`` of them in every
        parameter, matrix-free.

        Each iterate is recorded with ``track_mean_square``, the mean square position residual
        per axis [m²] on the training tracks, ``val_track_mean_square``, the same on the
        validation tracks (their start states fitted to each iterate), ``val_forecast``, the RMS
        position error [m] of forecasts of the validation tracks (:class:`ForecastScore`: from an
        origin every 2 s, 1 s of history, 5 s ahead, as ``fhnn predict`` forecasts), and the
        validation windows' terms. The fit's own objective chooses, the forecasts guard: each
        iterate becomes the best model if it forecasts the validation tracks no worse than the
        phase's start (``best_val`` is then its validation windows' loss, which hold little of
        what this phase fits), so the phase ends at its last such iterate. A resumed run starts
        the phase again from its best model with the iterations left;
        an iteration that no damping makes descend, or the time budget spent, ends the phase; a
        model without :meth:`~fhnn.models.base.AbstractModel.track_parameters` skips it."""
        cfg = self.config
        first = cfg.steps + cfg.lbfgs_steps
        left = self.total_steps - max(state.step, first)
        start = state.best_model
        free = start.track_parameters()
        if left <= 0 or free is None:
            state.step = self.total_steps
            return state
        done = self.total_steps - left
        if time.monotonic() >= self.deadline("tracks"):
            return self._tracks_not_begun(state, done, left)
        split, parent = fitted_pieces(self.train_split, cfg.track_samples, cfg.seed)
        n_tracks = self.train_split.n_traj
        weights = None
        if cfg.bootstrap:  # each piece weighted as its track
            weights = bootstrap_weights(np.arange(n_tracks), n_tracks, cfg.seed)[parent]
        began = time.monotonic()
        fit = TrackFit(start, free, split, weights)
        # an iteration costs about what setting the fit up did (its programs, the start states)
        took = time.monotonic() - began
        if time.monotonic() + took >= self.deadline("tracks"):  # before the validation fits' setup
            return self._tracks_not_begun(state, done, left)
        val_pieces = track_pieces(self.val_split, cfg.track_samples, cfg.seed + 6)[0]
        held_out = TrackFit(start, free, val_pieces)
        forecasts = ForecastScore(start, free, self.val_split, cfg.track_samples, cfg.seed + 7)
        guard = forecasts(fit.theta)
        if time.monotonic() + took >= self.deadline("tracks"):
            return self._tracks_not_begun(state, done, left)
        whole_from = cfg.track_steps - cfg.track_whole  # the first matrix-free iteration's index
        for k in range(left):
            began = time.monotonic()
            index = cfg.track_steps - left + k  # among the phase's iterations, from 0
            if cfg.track_whole and index == max(whole_from, cfg.track_steps - left):
                # from here every weight moves: the fit and the validation scores in all of them
                whole = fit.model.track_parameters(whole=True)
                fit = fit.freeing(whole)
                held_out = TrackFit(fit.model, whole, val_pieces)
                forecasts = ForecastScore(fit.model, whole, self.val_split, cfg.track_samples, cfg.seed + 7)
            if index >= whole_from:
                result = fit.step_matrix_free(cfg.track_cg_steps)
            else:
                result = fit.step(cfg.track_chord)
            done += 1
            self._tell("tracks", done)
            if not result.accepted:
                state.stopped = (
                    f"the whole-track fit stopped at iteration {k + 1} of {left}: no step lowered "
                    f"its objective (damping {result.damping:.1e})"
                )
                state.step = self.total_steps
                break
            record: dict[str, Any] = {"step": done, "phase": "tracks", "iteration": k + 1}
            if k == 0:
                record["val_track_mean_square_start"] = held_out.mean_square
                record["val_forecast_start"] = guard
                record["tracks"] = fit.n_tracks  # tracks (or pieces of them) in the fit
                record["val_tracks"] = held_out.n_tracks
                record["val_forecasts"] = forecasts.n_forecasts
            record["track_mean_square"] = result.mean_square
            record["val_track_mean_square"] = held_out.rescore(fit.theta)
            record["val_forecast"] = forecasts(fit.theta)
            record["damping"] = result.damping
            val = self.validate(result.model)
            record.update({f"val_{name}": v for name, v in val.items()})
            state.history.append(record)
            state.model, state.step = result.model, done
            # no forecasts (every validation track shorter than a history): the objective alone
            if np.isnan(guard) or record["val_forecast"] <= guard:
                state.best_model, state.best_val = result.model, val["total"]
            took = time.monotonic() - began  # the next iteration's cost, as this one's
            late = (
                None
                if k + 1 == left
                else self._over_budget("tracks", k + 1, left, "the whole-track fit", took)
            )
            if late is not None:
                record["budget"] = True
                state.add_stop(late)
                state.step = self.total_steps
            if callback is not None:
                callback(state, record)
            if late is not None:
                break
        return state

    def _tracks_not_begun(self, state: TrainState, done: int, left: int) -> TrainState:
        """The whole-track fit cut by the budget before its first iteration (none would end in
        time): a record of the best model, marked for the next command to continue from."""
        record: dict[str, Any] = {"step": done, "phase": "tracks", "iteration": 0, "budget": True}
        record.update({f"val_{name}": v for name, v in self.validate(state.best_model).items()})
        state.history.append(record)
        late = (
            f"the whole-track fit stopped before iteration 1 of {left}: the time budget "
            f"({self.budget.describe('tracks')}) would run out during it, after {self.budget.spent():.0f} s"
        )
        state.add_stop(late)
        state.step = self.total_steps
        return state

    def quasi_newton_windows(self) -> Windows:
        """The training windows of the quasi-Newton phases: a seeded subset of ``lbfgs_pairs`` of
        those starting every ``lbfgs_stride`` samples from the first allowed start (all of them
        where fewer), in their original order; under ``bootstrap`` as many drawn with replacement
        in proportion to :attr:`window_weights`."""
        cfg = self.config
        pool = np.flatnonzero((self.train_pairs.start - cfg.first_start) % cfg.lbfgs_stride == 0)
        n = min(cfg.lbfgs_pairs, pool.size)
        rng = np.random.default_rng(cfg.seed + 2)
        if self.window_weights is None:
            pick = rng.choice(pool.size, n, replace=False)
        else:  # a bootstrap member: drawn with replacement in proportion to the weights
            w = self.window_weights[pool]
            pick = rng.choice(pool.size, n, replace=True, p=w / w.sum())
        return self.train_pairs.subset(pool[np.sort(pick)])

    def _quasi_newton(
        self,
        state: TrainState,
        start: AbstractModel,
        iterations: int,
        phase: str,
        callback: Callable[[TrainState, dict[str, float]], None] | None,
        restore: Callable[[AbstractModel], AbstractModel] = lambda m: m,
        give_up: Callable[[dict[str, Any]], bool] | None = None,
        offset: int = 0,
    ) -> TrainState:
        """``iterations`` full-batch quasi-Newton steps on the parameters of ``start``, on a seeded
        subset of the training pairs; validates and records ``restore(iterate)`` five times, the
        last at the last iterate, which ``state.model`` then holds (``phase`` "warmup": records at
        step 0; "lbfgs": at the steps after Adam's). ``give_up(record)`` true at a record, or the
        phase's time budget spent (:meth:`deadline`), ends the phase there."""
        cfg = self.config
        batch = self.batch(self.quasi_newton_windows(), jax.random.PRNGKey(cfg.seed + 4))
        weights = start.quasi_newton_weights(batch)
        if weights is not None:  # the model's window weights, held fixed through the phase
            batch = {**batch, "weight": weights}
        params, static = eqx.partition(start, eqx.is_array)
        flat, unravel = ravel_pytree(params)
        scales = self.scales

        qn_cfg = cfg.only(QUASI_NEWTON_FIELDS)
        # the vector and the optimiser's state are donated to each iteration's outputs, so the
        # ~7 MB memory is updated in place, not copied (the same bits); each leaf needs
        # a buffer of its own for that (optax's zeros may share one) and ``start`` must keep its own
        flat = jnp.array(flat, copy=True)
        opt_state = jax.tree.map(
            lambda x: jnp.array(x, copy=True) if eqx.is_array(x) else x,
            strong_types(optax.lbfgs(memory_size=cfg.lbfgs_memory).init(flat)),
        )
        every = max(1, min(cfg.val_every, iterations // 5 or 1))
        what = "the warm-up" if phase == "warmup" else "the L-BFGS polish"
        of = offset + iterations
        for k in range(iterations):
            began = time.monotonic()
            flat, opt_state, value = self._program(
                phase,
                quasi_newton_step,
                flat,
                opt_state,
                params,
                static,
                batch,
                scales,
                qn_cfg,
                donate=(0, 1),
            )
            done = offset + k + 1
            self._tell(phase, 0 if phase == "warmup" else cfg.steps + done)
            took = time.monotonic() - began if k else 0.0  # the first includes its compilation
            late = None if done == of else self._over_budget(phase, done, of, what, took)
            if (k + 1) % every == 0 or done == of or late is not None:
                record = {"step": 0 if phase == "warmup" else cfg.steps + done, "train_loss": float(value)}
                record.update({"phase": phase, "iteration": done})
                self._record(state, restore(eqx.combine(unravel(flat), static)), record, callback, late=late)
                if give_up is not None and give_up(record):
                    break
            if late is not None:
                if phase == "lbfgs":  # the whole-track fit waits for the polish to be continued
                    state.step = self.total_steps
                break
        return state

    def _record(
        self,
        state: TrainState,
        model: AbstractModel,
        record: dict[str, Any],
        callback: Callable[[TrainState, dict[str, float]], None] | None,
        *,
        stop: TrainConfig | None = None,
        late: str | None = None,
    ) -> bool:
        """Validate ``model``, log ``record`` with the validation terms, keep the best model,
        advance ``state`` to ``record["step"]`` and call ``callback``. Under an Adam configuration
        ``stop`` (when given) whose guard fires (:func:`stop_reason`), ``state.stopped`` says why
        and ``state.step`` jumps to the end of the Adam phase — before ``callback`` saves the
        checkpoint, so a resumed run goes on to the polish, not back into Adam; ``late`` (the time
        budget ran out, in any phase) is appended to ``state.stopped`` and stops Adam the same
        way. Returns whether this record ended the phase."""
        val = self.validate(model)
        record.update({f"val_{k}": v for k, v in val.items()})
        if late is not None:  # the next command continues from here (budget.rewind_cut)
            record["budget"] = True
        state.history.append(record)
        if val["total"] < state.best_val:
            state.best_val, state.best_model = val["total"], model
        state.model, state.step = model, record["step"]
        reason = None if stop is None else stop_reason(state.history, stop)
        if reason is not None:
            state.stopped = f"Adam stopped at step {record['step']} of {stop.steps}: {reason}"
        elif late is not None:
            state.add_stop(late)
        ended = reason is not None or late is not None
        if stop is not None and ended:
            state.step = stop.steps
        if callback is not None:
            callback(state, record)
        return ended

    def _tell(self, phase: str, step: int) -> None:
        if self._on_step is not None:
            self._on_step(phase, step)

    @staticmethod
    def optimizer_for(config: TrainConfig) -> optax.GradientTransformation:
        """Adam with the configuration's piecewise-constant learning rate; with ``lr_c_l ≠ 1`` the
        parameters named in :data:`CONSTANT_LEAVES` step at ``lr_c_l`` times that rate."""
        return AdamSettings.of(config).optimizer()

    def init(self, model: AbstractModel) -> TrainState:
        opt_state = self.optimizer.init(eqx.filter(model, eqx.is_array))
        return TrainState(
            model=model, opt_state=opt_state, step=0, best_model=model, best_val=np.inf, history=[]
        )

    def validate(self, model: AbstractModel) -> dict[str, float]:
        """Loss terms on the validation windows, and ``total``: their data sum weighted as the
        training loss weighs them (:func:`data_loss`), so a term trained with weight 0 — the
        derivative loss against estimated derivatives — does not choose the best model."""
        raw = self._program("validate", _validation_terms, model, self._val, self.scales)
        terms = {k: float(v) for k, v in raw.items()}
        terms["total"] = float(data_loss(raw, self.config))
        return terms

    def run(
        self,
        state: TrainState,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
        checkpoint: Callable[[TrainState], None] | None = None,
        checkpoint_seconds: float = 60.0,
    ) -> TrainState:
        """Train from ``state.step`` up to ``until`` (default: ``config.steps``). ``callback`` is
        called at every validation; ``checkpoint(state)`` also whenever ``checkpoint_seconds`` have
        passed since the last call or validation, so that a kill between validations loses little
        (a run resumed from there gives the same result as an uninterrupted one)."""
        until = self.config.steps if until is None else min(until, self.config.steps)
        _adam_phase([self], [state], [callback], [checkpoint], until, checkpoint_seconds)
        return state
