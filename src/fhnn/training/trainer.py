"""Training of any :class:`~fhnn.models.base.AbstractModel` on a data set (SPEC §5).

Loss ``L = w_deriv L_deriv + w_step L_step + λ_flow(step) L_flow``:

- ``L_deriv``: MSE of ``f(s, t, F(t))`` against the stored true derivatives, per component divided
  by the training set's standard deviation of that component (so positions, velocities and
  accelerations weigh alike);
- ``L_step``: MSE of one RK4 step over ``dt`` (with the exact forcing ``F(t)`` inside the step)
  against the next observed state, per component divided by the std of the observed increments;
- ``L_flow``: the model's regularisation (FHNN: mean ``‖Hψ‖²_F`` at the batch positions). Its
  weight anneals linearly from ``lambda_flow`` to 0 over the first ``flow_anneal`` fraction of the
  steps, so its bias towards zero-curvature flows (a vortex has curvature) is gone by the end.

Four phases:

1. Warm-up (``warmup_steps`` quasi-Newton iterations; only for models whose
   :meth:`~fhnn.models.base.AbstractModel.warmup` names a part): the part is fitted full-batch
   first. FHNN with a linear far field fits its linear flow and coefficient net this way before
   the stream MLP joins, so the MLP learns only what a linear flow cannot explain (on
   ``solid_body_vortex`` the warm-up alone recovers Ω to 1e-5 relative); without the MLP an
   iteration costs a third of one on the whole model.
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

The quasi-Newton phases run on a fixed, seeded subset of ``lbfgs_pairs`` windows (the data
terms, no regulariser), drawn from those starting every ``lbfgs_stride`` samples, with L-BFGS
keeping ``lbfgs_memory`` curvature pairs (100 by default: on the solid_body_vortex warm-up, 10
pairs left the validation loss at 5.9e-7 after 300 iterations, 100 pairs reached 1.2e-7). They
are deterministic; a run interrupted inside one restarts that phase from the last checkpoint.
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

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import Split
from fhnn.data.windows import LossScales, Windows
from fhnn.errors import ConfigError
from fhnn.executables import StoredProgram
from fhnn.models.base import AbstractModel
from fhnn.training.tracks import ForecastScore, TrackFit, track_pieces

Array = jax.Array


#: The values of ``TrainConfig.shoot_drift``.
SHOOT_DRIFTS = ("free", "model")


@frozen_config
class TrainConfig(Config):
    """Optimisation settings.

    Attributes:
        steps: Adam steps (0: quasi-Newton phases only).
        batch_size: transition pairs per step.
        lr: initial learning rate.
        lr_boundaries: fractions of ``steps`` at which the rate is multiplied by ``lr_decay``.
        lr_decay: factor at each boundary.
        w_deriv, w_step: weights of the derivative and one-step losses.
        lambda_flow: initial weight of the flow-smoothness term.
        flow_anneal: fraction of the steps over which ``lambda_flow`` decays linearly to 0.
        seed: seed of initialisation and batch order (and of the weights under ``bootstrap``).
        val_every: steps between validations (the best validation model is kept).
        val_pairs: at most this many validation pairs are used per validation.
        warmup_steps: quasi-Newton iterations on the model's warm-up parameters before Adam.
        lbfgs_steps: quasi-Newton polish iterations after Adam (0: none).
        track_steps: Levenberg–Marquardt iterations on the whole training tracks after Adam and
            the polish, from the best model so far (0: none; :mod:`fhnn.training.tracks`; only for
            models that name their :meth:`~fhnn.models.base.AbstractModel.track_parameters`).
        track_samples: the most samples (tracks × their padded length) the whole-track fit
            holds, on the training tracks and on the validation tracks each; larger splits are
            cut into pieces and a seeded subset kept (:func:`~fhnn.training.tracks.track_pieces`),
            so an iteration's cost does not grow with the data (issue 14's 49 training tracks of
            20 s, 19,257 samples padded, fit whole).
        lbfgs_pairs: training pairs (a seeded subset) in the quasi-Newton phases.
        lbfgs_memory: curvature pairs kept by L-BFGS.
        shoot: samples per example of the multi-step (multiple-shooting) loss on positions (0 or
            2: off). With ``k ≥ 3`` every example is ``k`` consecutive samples of a trajectory,
            each with its own times: RK4 from the first, one step per sample interval, and the
            predicted positions are compared with the observed ones at every later sample — a
            loss that needs neither measured velocities nor derivatives (``fhnn train`` turns it
            on for data whose velocities were estimated).
        w_shoot: weight of the multi-step loss.
        shoot_skip: the multi-step windows start at this sample of a trajectory or later (on
            both splits): a smoother's velocity estimate at a trajectory's first samples sees one
            side of it only and is several times worse than inside (issue 14's data: 15, 9.8,
            6.7, 4.5 mm/s at samples 0–3 and 1.5 mm/s inside), and a window's prediction starts
            from it.
        lbfgs_stride: the quasi-Newton phases draw their ``lbfgs_pairs`` examples from the
            windows starting every ``lbfgs_stride`` samples (from ``shoot_skip``); with the
            multi-step loss, ``shoot − 1`` tiles each trajectory with windows that share only
            their end samples, so every interval of the data enters the polish once.
        lr_c_l: multiplier of the learning rate of a constant linear drag (the FHNN's
            ``c_l_raw``; other models have none) and of constant added masses (``mass_raw``,
            with ``added_mass="constant"``). Adam moves a parameter by about the rate times
            its gradient's mean over its spread; c_l's gradient is noisy and the c_q net soaks up
            its error (c_q(σ) ≈ 1/σ at small σ mimics a linear drag), so at the plain rate c_l
            barely leaves its initial value in a short run (issue 14's data: 2.0 → 2.2 in 4,000
            steps, truth 3.0, on clean data as on noisy). A constant mass is one such value too.
        shoot_noise: ``(σ_x [m], σ_v [m/s])``, the noise of the observed positions and the error
            of the estimated velocity a multi-step window starts from ((0, 0): not modelled).
            With ``σ_x > 0`` the multi-step loss weighs each window's position residuals ``r``
            (per axis) by the inverse of their covariance under those errors,
            ``rᵀ (I + J P Jᵀ)⁻¹ r`` with ``J = [1, t]`` (a start error's drift, free flight over the
            window) and ``P = diag(1, σ_v²/σ_x²)``: the model gains nothing by damping a start
            error it cannot see, which otherwise biases the drag up where relative speeds are
            small (the error is noise the data's drag signal must outweigh there).
        shoot_drift: how a start error drifts in that weighting: ``"free"``, in free flight
            (``J = [1, t]`` per axis); ``"model"``, as the model itself carries it — ``J`` the
            window's predicted positions' derivatives with respect to its start state (forward
            mode, held fixed in the gradient as generalised least squares holds its weights;
            :func:`fhnn.models.base.start_error_weighted_by`), damped by the drag and turned by
            the flow, which free flight overstates on windows long against the drag's time
            ``(M + m_a)/c`` (about 6 s on issue 14's data). Measured there (``benchmarks/own_data.py
            --set train.shoot_drift=model``, data seeds 0 / 1): the validation forecast at 5 s
            2.24 → 2.13 / 2.30 → 2.27 mm, ``c_l`` 2.2 → 2.8 / 8.1 → 8.5 % off, a step about twice
            as dear; not the default.
        warmup_accept: what the warm-up's validation loss decides (0: nothing — Adam always
            follows the warm-up). Above 0, a warm-up whose validation loss is at or below it is
            kept and the Adam phase is skipped (the polish starts from the warm-up: the linear
            far field and the coefficients explain the data, and quasi-Newton finishes the job);
            a warm-up above it is discarded and Adam starts from the initial model (a far field
            that cannot explain the flow drives the coefficients to a corner Adam does not leave:
            on ``steady_vortex`` the warm-up sent c_l to 0). The decision is logged in the
            warm-up's last history record (``"warmup": "kept"`` or ``"discarded"``).
        max_time: wall-clock budget in seconds for the training in one process, compilation
            left out (0: none); see
            :meth:`Trainer.deadline`. A phase cut short by it says so in ``stopped``.
        bootstrap: train on a Bayesian bootstrap of the training trajectories drawn from the
            seed (each trajectory's windows weighted by its own random weight, see
            :func:`bootstrap_weights`; the validation split is left whole). ``fhnn train
            --seeds N`` sets it, so the spread of an ensemble's members holds the data's
            sampling noise as well as that of their initialisation and batch order: on issue
            14's data the members trained on the same
            data agreed on the added masses to 0.1–0.4 % while their median was 0.5 % off.
        stop_rising: the Adam phase ends early once the validation loss has risen at this many
            validations in a row (0: never); the polish, if any, then starts from the best model,
            as it always does. Six rises in a row — seven
            increasing values — happen by chance with probability 1/5040 in a loss that only
            fluctuates, so the guard catches a diverging or overfitting run, not noise.
    """

    config_name = "training"

    steps: int = 20000
    batch_size: int = 256
    lr: float = 3e-3
    lr_boundaries: tuple[float, ...] = (0.4, 0.6, 0.8, 0.9)
    lr_decay: float = 0.3
    w_deriv: float = 1.0
    w_step: float = 1.0
    lambda_flow: float = 1e-6
    flow_anneal: float = 0.5
    seed: int = 0
    val_every: int = 500
    val_pairs: int = 8192
    warmup_steps: int = 0
    lbfgs_steps: int = 0
    track_steps: int = 0
    track_samples: int = 25_000
    lbfgs_pairs: int = 8192
    lbfgs_memory: int = 100
    warmup_accept: float = 0.0
    max_time: float = 0.0
    stop_rising: int = 6
    shoot: int = 0
    w_shoot: float = 1.0
    shoot_skip: int = 0
    lbfgs_stride: int = 1
    lr_c_l: float = 1.0
    shoot_noise: tuple[float, float] = (0.0, 0.0)
    shoot_drift: str = "free"
    bootstrap: bool = False

    def validate(self) -> None:
        check_positive(self, "batch_size", "lr", "lr_decay", "val_every", "val_pairs", "lbfgs_pairs")
        check_positive(self, "lbfgs_memory", "track_samples")
        check_nonnegative(self, "w_deriv", "w_step", "lambda_flow", "flow_anneal", "seed", "lbfgs_steps")
        check_nonnegative(self, "steps", "warmup_steps", "stop_rising", "shoot", "w_shoot", "shoot_skip")
        check_nonnegative(self, "track_steps")
        check_positive(self, "lbfgs_stride", "lr_c_l")
        check_nonnegative(self, "warmup_accept", "max_time")
        if self.shoot == 1:
            raise ConfigError("training: shoot must be 0 (off) or at least 2 samples, got 1")
        if any(not 0 < b < 1 for b in self.lr_boundaries):
            raise ConfigError(f"training: lr_boundaries must lie in (0, 1), got {self.lr_boundaries}")
        if self.shoot_drift not in SHOOT_DRIFTS:
            raise ConfigError(
                f"training: shoot_drift must be one of {', '.join(SHOOT_DRIFTS)}, got {self.shoot_drift!r}"
            )
        sx, sv = self.shoot_noise
        if not (np.isfinite(sx) and np.isfinite(sv) and sx >= 0 and sv >= 0) or (sv > 0 and sx == 0):
            raise ConfigError(
                f"training: shoot_noise must be two finite values >= 0 (the position noise > 0 "
                f"where the velocity error is), got {self.shoot_noise}"
            )

    def start_variance(self, n: int) -> dict[str, Array]:
        """The batch field ``"start_var"`` of ``n`` windows: the variances of a window's start
        position and velocity errors relative to the position noise (``1`` and ``σ_v²/σ_x²``
        [1/s²], see ``shoot_noise``), shape ``(n, 2)`` (per axis, ``shoot_drift="free"``) or
        ``(n, 4)`` (per start-state component ``x, y, vx, vy``, ``"model"``); empty where the
        multi-step loss is off or no noise is given."""
        sx, sv = self.shoot_noise
        if self.shoot < 3 or sx == 0:
            return {}
        var = [1.0, (sv / sx) ** 2]
        if self.shoot_drift == "model":
            var = [var[0], var[0], var[1], var[1]]
        return {"start_var": jnp.broadcast_to(jnp.asarray(var), (n, len(var)))}

    @property
    def first_start(self) -> int:
        """The first sample of a trajectory a training window may start at: ``shoot_skip`` with
        the multi-step loss (``shoot ≥ 3``), else 0."""
        return self.shoot_skip if self.shoot >= 3 else 0

    def only(self, fields: tuple[str, ...]) -> TrainConfig:
        """This configuration with every field but ``fields`` at its default: the static argument
        of a compiled program that reads only ``fields``, so runs differing elsewhere (the seed,
        the validation interval) share one program."""
        return TrainConfig(**{f: getattr(self, f) for f in fields})

    def regularizes(self, step: int) -> bool:
        """Whether Adam step ``step`` (0-based) computes the flow penalty. Once its annealed weight
        is zero the penalty is skipped (a second compiled step without it, ~18 % faster on FHNN) —
        when at least :data:`PENALTY_FREE_MIN_STEPS` steps are left to gain the second program's
        compilation (~5 s) back."""
        if self.lambda_flow <= 0 or self.flow_anneal <= 0:
            return False
        end = self.flow_anneal * self.steps
        return step < end or self.steps - end < PENALTY_FREE_MIN_STEPS


#: Fields read by the quasi-Newton iteration (see :meth:`TrainConfig.only`).
QUASI_NEWTON_FIELDS = ("w_deriv", "w_step", "w_shoot", "lbfgs_memory")

#: Adam steps without the flow penalty it takes to gain a second compiled step back: the step
#: without it is 1.8 ms faster on FHNN at batch 256 and compiles in ~5 s (training_speed.py).
PENALTY_FREE_MIN_STEPS = 5000

#: A warm-up is abandoned (and discarded) at a record whose validation loss is above this many
#: times ``warmup_accept``: more than a warm-up was seen to fall in the rest of its iterations
#: (``solid_body_vortex``: 230× from iteration 40 to 400; ``steady_vortex`` stays at 0.13 from
#: iteration 40 on, ``time_varying_vortex`` at 0.17).
WARMUP_GIVE_UP = 1e4

#: Share of ``max_time`` that the phases before an L-BFGS polish may use (the polish gets the rest:
#: an iteration on the whole model costs ~25 Adam steps, and it is what brings the loss below
#: Adam's noise floor).
PRE_POLISH_SHARE = 0.5

#: Adam steps run as one compiled program between the trainer's looks at the clock (at most; see
#: :func:`adam_chunk_end`), and the wall time a chunk should not exceed once a step's time is known
#: (so a time budget is still checked every half second with slow steps).
ADAM_CHUNK = 50
CHUNK_SECONDS = 0.5

#: Loss terms that are regularisers: weighted by the annealed ``lambda_flow``, left out of validation.
REGULARIZERS = ("flow",)


def loss_terms(
    model: AbstractModel, batch: dict[str, Array], scales: tuple[Array, Array]
) -> dict[str, Array]:
    """The model's unweighted loss terms on a batch (see :meth:`AbstractModel.loss_terms`)."""
    return model.loss_terms(batch, scales)


#: The data terms whose weights the configuration sets (``w_deriv``, ``w_step``, ``w_shoot``).
DATA_TERMS = ("deriv", "step", "shoot")


def term_weight(name: str, config: TrainConfig) -> float:
    """The weight of data term ``name`` in the loss: ``w_deriv``, ``w_step``, ``w_shoot``, or 1
    for a model-specific objective term."""
    return {"deriv": config.w_deriv, "step": config.w_step, "shoot": config.w_shoot}.get(name, 1.0)


def data_loss(terms: dict[str, Array], config: TrainConfig) -> Array:
    """Weighted sum of the data terms: ``w_deriv·deriv + w_step·step + w_shoot·shoot`` plus any model-specific
    objective term (weight 1); regularisers excluded. A term of weight 0 is left out, not
    multiplied by 0, so a compiled loss that only this sum reads does not compute it at all (the
    one-step RK4 term is ~2/3 of an FHNN step's cost)."""
    weighted = ((term_weight(k, config), v) for k, v in terms.items() if k not in REGULARIZERS)
    return sum((w * v for w, v in weighted if w), jnp.zeros(()))


class AdamSettings(eqx.Module):
    """The Adam phase's settings as its compiled programs read them (:func:`adam_step`,
    :func:`adam_chunk`): its numbers — learning rate and schedule, loss weights, the penalty's
    weight and annealing — are arrays, arguments of the program rather than constants in it, so
    runs that differ only in them (``steps``, ``lr``, a non-zero weight; a run extended to more
    steps) share one compiled program; what shapes the program is static: the batch size, which
    data terms have a non-zero weight, whether the penalty anneals, whether ``c_l`` has its own
    rate. Build it with :meth:`of`. The learning rate is optax's piecewise-constant schedule of
    ``lr`` ×``lr_decay`` at each ``lr_boundaries`` fraction of ``steps``, the penalty's weight
    ``lambda_flow`` decaying linearly to 0 over the first ``flow_anneal`` of the steps, the data loss
    :func:`data_loss`."""

    batch_size: int = eqx.field(static=True)
    weighted: tuple[str, ...] = eqx.field(static=True)
    annealed: bool = eqx.field(static=True)
    split_c_l: bool = eqx.field(static=True)
    lr: Array
    thresholds: Array  # (len(lr_boundaries),) int: steps at which the rate is multiplied by ``scales``
    scales: Array  # (len(lr_boundaries),): lr_decay; 1 for a boundary that falls on an earlier one's step
    lr_c_l: Array
    weights: dict[str, Array]  # data term → its weight, for the terms in ``weighted``
    lambda_flow: Array
    anneal_end: Array  # flow_anneal · steps

    @classmethod
    def of(cls, config: TrainConfig) -> AdamSettings:
        # optax's piecewise-constant schedule takes {step: factor}: boundaries that fall on one
        # step count once; a repeat keeps its place in the (static) length with factor 1
        steps = sorted({int(b * config.steps) for b in config.lr_boundaries})
        pad = len(config.lr_boundaries) - len(steps)
        weights = {k: term_weight(k, config) for k in DATA_TERMS}
        number = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
        return cls(
            batch_size=config.batch_size,
            weighted=tuple(k for k, w in weights.items() if w != 0.0),
            annealed=config.flow_anneal > 0,
            split_c_l=config.lr_c_l != 1.0,
            lr=number(config.lr),
            thresholds=jnp.asarray(steps + steps[-1:] * pad, dtype=int),
            scales=number([config.lr_decay] * len(steps) + [1.0] * pad),
            lr_c_l=number(config.lr_c_l),
            weights={k: number(w) for k, w in weights.items() if w != 0.0},
            lambda_flow=number(config.lambda_flow),
            anneal_end=number(config.flow_anneal * config.steps),
        )

    def rate(self, count: Array) -> Array:
        """The learning rate at Adam step ``count`` (optax's piecewise-constant schedule)."""
        v = self.lr
        for k in range(self.thresholds.shape[0]):
            indicator = jnp.maximum(0.0, jnp.sign(self.thresholds[k] - count))
            v = v * indicator + (1 - indicator) * self.scales[k] * v
        return v

    def optimizer(self) -> optax.GradientTransformation:
        """Adam at :meth:`rate`; with ``lr_c_l ≠ 1`` the parameters named in
        :data:`CONSTANT_LEAVES` (a constant linear drag, constant added masses) step at
        ``lr_c_l`` times that rate."""
        if not self.split_c_l:
            return optax.adam(self.rate)
        fast = optax.adam(lambda i: self.lr_c_l * self.rate(i))
        # a model without c_l_raw (a baseline, linear_drag="net") has every leaf in "rest"
        return optax.multi_transform({"rest": optax.adam(self.rate), "c_l": fast}, _c_l_labels)

    def flow_weight(self, step: Array) -> Array:
        """The flow penalty's weight at Adam step ``step``."""
        if not self.annealed:
            return jnp.asarray(0.0)
        return self.lambda_flow * jnp.clip(1.0 - step / self.anneal_end, 0.0, 1.0)

    def counts(self, name: str) -> bool:
        """Whether data term ``name`` enters the loss (a model-specific objective term always does)."""
        return name in self.weighted or name not in DATA_TERMS

    def data_loss(self, terms: dict[str, Array]) -> Array:
        """:func:`data_loss` with these weights: terms of weight 0 are left out, not multiplied by 0."""
        weighted = (
            (self.weights[k] if k in DATA_TERMS else 1.0, v)
            for k, v in terms.items()
            if k not in REGULARIZERS and self.counts(k)
        )
        return sum((w * v for w, v in weighted), jnp.zeros(()))


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


#: The stream of :func:`bootstrap_weights`'s generator beside the seed (apart from the others).
BOOTSTRAP_STREAM = 5


def bootstrap_weights(traj: np.ndarray, n_traj: int, seed: int) -> np.ndarray:
    """Weights ``(P,)`` of windows from trajectories ``traj`` ``(P,)`` (indices below ``n_traj``)
    under a Bayesian bootstrap of the trajectories drawn from ``seed`` (Rubin 1981): the
    trajectories' weights are ``n_traj`` times a draw from the flat Dirichlet law — positive,
    mean 1, sum ``n_traj``, each about exponentially distributed — and each window takes its
    trajectory's. Whole trajectories are weighted, not windows: neighbouring windows share samples
    and noise, so they are not independent draws.

    Unlike the classical resample (``n_traj`` draws with replacement), no trajectory is left out
    (that one drops about a third of them, and a member then extrapolates its coefficients over
    the parts of the (r, σ) range only those trajectories covered). Measured on issue 14's data
    (``benchmarks/own_data.py``, data seed 0), the two agree within their noise: ten members of
    each hold the masses' truth at 100 % of points, c_q's at 97 % and c_l's at 100 %, with
    intervals 0.9–1.1 %, 22 % and 13.6 % wide, members' median c_l 6.9 % / 6.0 % off
    (``docs/benchmarks/own_data_seeds10*.json``). The differences three members showed (m_ax
    held at 81 % against 51 %) were chance."""
    rng = np.random.default_rng([seed, BOOTSTRAP_STREAM])
    weights = n_traj * rng.dirichlet(np.ones(n_traj))
    return weights[traj]


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
    ) -> None:
        """``on_step(phase, step)`` (optional) is told of progress between records, after every
        quasi-Newton step and every chunk of Adam steps (:func:`adam_chunk_end`; a cheap call: a
        progress bar throttles its own redrawing); phase is "warmup", "adam" or "lbfgs", step
        counts as in the history."""
        self.config = config
        self._on_step = on_step
        #: The start of ``config.max_time``: when this trainer was made, moved later by each
        #: compiled program's first call (:meth:`_uncounted_first`; see :meth:`deadline`).
        self.started = time.monotonic()
        #: Seconds of the budget a discarded warm-up used: sunk, the later phases share the rest
        #: from the moment of the discard (see :meth:`deadline`).
        self._sunk = 0.0
        #: The compiled programs by name (executables kept on disk: :mod:`fhnn.executables`);
        #: the first call of each (its compilation or loading) is left out of the budget.
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
        """When ``phase`` ("warmup", "adam", "lbfgs" or "tracks") must end under ``config.max_time``
        (``time.monotonic()`` seconds; infinite without a budget). The budget counts from the
        trainer's creation (a resumed run starts a new one) and leaves out the first call of each
        compiled program (:meth:`_uncounted_first`: its compilation). When a
        polish or a whole-track fit follows, the phases before it end at :data:`PRE_POLISH_SHARE`
        of the budget, so the polish (and the whole-track fit) — from the best model so far — gets
        the rest; they end at the budget. The
        time of a discarded warm-up is sunk: Adam and the polish then split what is left in the
        same shares (without it, a warm-up that took half the budget before being discarded left
        Adam one step: ``steady_vortex`` at ``max_time=60``)."""
        cfg = self.config
        if cfg.max_time <= 0:
            return np.inf
        final = cfg.lbfgs_steps > 0 or cfg.track_steps > 0  # a polish or whole-track fit follows
        share = PRE_POLISH_SHARE if phase not in ("lbfgs", "tracks") and final else 1.0
        return self.started + self._sunk + share * (cfg.max_time - self._sunk)

    def _uncounted_first(
        self, name: str, program: Callable[..., Any], *args: Any, donate: tuple[int, ...] = ()
    ) -> Any:
        """``program(*args)``; its first time under ``name`` in this trainer — a compiled program's first
        call: tracing and compilation, or loading from the persistent cache — is left out of the
        budget, so what a job trains for does not depend on the state of the cache (a trial at
        ``max_time=60`` on ``steady_vortex``: 261 Adam steps on a cold cache, all 1,500 warm).
        The arrays of the arguments at positions ``donate`` are given to the program's outputs
        (:class:`~fhnn.executables.StoredProgram`): the caller must not use them again."""
        stored = self._programs.get(name)
        if stored is not None:
            return stored(*args)
        stored = self._programs[name] = StoredProgram(program, donate=donate)
        t0 = time.monotonic()
        out = jax.block_until_ready(stored(*args))
        self.started += time.monotonic() - t0
        return out

    def _over_budget(self, phase: str, step: int, of: int, what: str) -> str | None:
        """The ``stopped`` text when ``phase`` has run past its :meth:`deadline`, else ``None``."""
        if time.monotonic() < self.deadline(phase):
            return None
        cfg = self.config
        spent = time.monotonic() - self.started
        unit = "step" if phase == "adam" else "iteration"
        share = (
            ""
            if phase in ("lbfgs", "tracks") or (cfg.lbfgs_steps == 0 and cfg.track_steps == 0)
            else f", {PRE_POLISH_SHARE:.0%} of it before the polish"
            if self._sunk == 0
            else f", {PRE_POLISH_SHARE:.0%} of the {cfg.max_time - self._sunk:.0f} s a discarded warm-up "
            "left before the polish"
        )
        return (
            f"{what} stopped at {unit} {step} of {of}: the time budget "
            f"(train.max_time={cfg.max_time:g} s{share}) ran out after {spent:.0f} s"
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
            self._sunk = min(time.monotonic() - self.started, self.config.max_time)
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
        """Quasi-Newton on all parameters from the best model so far."""
        return self._quasi_newton(state, state.best_model, self.config.lbfgs_steps, "lbfgs", callback)

    def track_fit(
        self, state: TrainState, callback: Callable[[TrainState, dict[str, float]], None] | None = None
    ) -> TrainState:
        """The whole-track fit: ``track_steps`` Levenberg–Marquardt iterations on every training
        track (:class:`~fhnn.training.tracks.TrackFit`; under ``bootstrap`` each track weighted as
        its windows are) from the best model so far.

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
        split, parent = track_pieces(self.train_split, cfg.track_samples, cfg.seed + 5)
        n_tracks = self.train_split.n_traj
        weights = None
        if cfg.bootstrap:  # each piece weighted as its track
            weights = bootstrap_weights(np.arange(n_tracks), n_tracks, cfg.seed)[parent]
        fit = TrackFit(start, free, split, weights)
        held_out = TrackFit(start, free, track_pieces(self.val_split, cfg.track_samples, cfg.seed + 6)[0])
        forecasts = ForecastScore(start, free, self.val_split, cfg.track_samples, cfg.seed + 7)
        guard = forecasts(fit.theta)
        done = self.total_steps - left
        for k in range(left):
            result = fit.step()
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
            late = None if k + 1 == left else self._over_budget("tracks", k + 1, left, "the whole-track fit")
            if late is not None:
                state.stopped = f"{state.stopped}; {late}" if state.stopped else late
                state.step = self.total_steps
            if callback is not None:
                callback(state, record)
            if late is not None:
                break
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
        # ~7 MB memory is updated in place, not copied (an iteration at 2,000 pairs 5.14 against
        # 5.42 ms on the 2-core CPU, benchmarks/lbfgs_overhead.py; the same bits); each leaf needs
        # a buffer of its own for that (optax's zeros may share one) and ``start`` must keep its own
        flat = jnp.array(flat, copy=True)
        opt_state = jax.tree.map(
            lambda x: jnp.array(x, copy=True) if eqx.is_array(x) else x,
            strong_types(optax.lbfgs(memory_size=cfg.lbfgs_memory).init(flat)),
        )
        every = max(1, min(cfg.val_every, iterations // 5 or 1))
        what = "the warm-up" if phase == "warmup" else "the L-BFGS polish"
        for k in range(iterations):
            flat, opt_state, value = self._uncounted_first(
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
            done = k + 1
            self._tell(phase, 0 if phase == "warmup" else cfg.steps + done)
            late = None if done == iterations else self._over_budget(phase, done, iterations, what)
            if done % every == 0 or done == iterations or late is not None:
                record = {"step": 0 if phase == "warmup" else cfg.steps + done, "train_loss": float(value)}
                record.update({"phase": phase, "iteration": done})
                self._record(state, restore(eqx.combine(unravel(flat), static)), record, callback, late=late)
                if give_up is not None and give_up(record):
                    break
            if late is not None:
                if phase == "lbfgs":
                    state.step = self.total_steps  # the run is over: a resume does not polish again
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
        state.history.append(record)
        if val["total"] < state.best_val:
            state.best_val, state.best_model = val["total"], model
        state.model, state.step = model, record["step"]
        reason = None if stop is None else stop_reason(state.history, stop)
        if reason is not None:
            state.stopped = f"Adam stopped at step {record['step']} of {stop.steps}: {reason}"
        elif late is not None:
            state.stopped = f"{state.stopped}; {late}" if state.stopped else late
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
        raw = self._uncounted_first("validate", _validation_terms, model, self._val, self.scales)
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


# The compiled programs of training. They are module-level functions whose data, scales and keys
# are arguments (not closed-over constants), as are the Adam phase's numbers (:class:`AdamSettings`);
# what shapes a program (the batch size, the terms in the loss, the quasi-Newton configuration) is
# a static, hashable argument. So a program is traced once per shape and structure in a process,
# and the persistent compilation cache (:func:`fhnn.runtime.use_compilation_cache`) and the
# stored executables (:mod:`fhnn.executables`) serve it to later processes.


@eqx.filter_jit
def _validation_terms(model: AbstractModel, data: dict[str, Array], scales: tuple[Array, Array]) -> dict:
    return loss_terms(model, data, scales)


def _adam_step(
    model: AbstractModel,
    opt_state: Any,
    i: Array,
    data: dict[str, Array],
    scales: tuple[Array, Array],
    key: Array,
    weights: Array | None,
    settings: AdamSettings,
    regularize: bool,
) -> tuple[AbstractModel, Any, dict[str, Array]]:
    """Adam step ``i`` on a minibatch of ``settings.batch_size`` pairs drawn from ``data`` with
    ``fold_in(key, i)``: uniformly, or with probabilities in proportion to ``weights`` ``(P,)``
    (a bootstrap member, see ``TrainConfig.bootstrap``; a window of weight 0 is never drawn).
    ``regularize`` (static): include the flow penalty at its annealed weight (False once that
    weight is zero: the penalty is then neither computed nor logged). A non-finite loss or gradient
    leaves model and optimiser state unchanged (``"skipped": 1``)."""
    n = next(iter(data.values())).shape[0]
    idx = draw_batch(jax.random.fold_in(key, i), n, settings.batch_size, weights)
    batch = {k: v[idx] for k, v in data.items()}
    batch["key"] = jax.random.fold_in(jax.random.fold_in(key, i), 1)
    weight = settings.flow_weight(i)

    def total(m: AbstractModel) -> tuple[Array, dict[str, Array]]:
        terms = loss_terms(m, batch, scales)
        # dropped terms (the penalty once its weight is zero, data terms of weight zero) are
        # outputs of nothing: XLA removes their computation
        terms = {k: v for k, v in terms.items() if (regularize if k in REGULARIZERS else settings.counts(k))}
        reg = sum((terms[k] for k in REGULARIZERS if k in terms), jnp.zeros(()))
        loss = settings.data_loss(terms) + weight * reg
        return loss, {**terms, "loss": loss}

    optimizer = settings.optimizer()
    grads, terms = eqx.filter_grad(total, has_aux=True)(model)
    updates, new_state = optimizer.update(grads, opt_state, eqx.filter(model, eqx.is_array))
    # a non-finite loss or gradient (e.g. an LNN's singular Hessian) skips the step instead of
    # destroying the weights; skipped steps are counted in the history
    flat = jax.tree_util.tree_leaves(eqx.filter(grads, eqx.is_array))
    finite = jnp.isfinite(terms["loss"]) & jnp.all(jnp.asarray([jnp.all(jnp.isfinite(g)) for g in flat]))
    keep = lambda new, old: jnp.where(finite, new, old)  # noqa: E731
    new_model = eqx.apply_updates(model, updates)
    params = jax.tree_util.tree_map(
        keep, eqx.filter(new_model, eqx.is_array), eqx.filter(model, eqx.is_array)
    )
    model = eqx.combine(params, model)
    opt_state = jax.tree_util.tree_map(
        lambda n, o: jnp.where(finite, n, o) if eqx.is_array(n) else n, new_state, opt_state
    )
    return model, opt_state, {**terms, "skipped": 1.0 - finite.astype(float)}


adam_step = eqx.filter_jit(_adam_step)


def draw_batch(key: Array, n: int, size: int, weights: Array | None = None) -> Array:
    """``size`` indices of ``n`` windows drawn with replacement with ``key``: uniformly, or with
    probabilities in proportion to ``weights`` ``(n,)`` (≥ 0, not all 0; a window of weight 0 is
    never drawn)."""
    if weights is None:
        return jax.random.randint(key, (size,), 0, n)
    return jax.random.choice(key, n, (size,), p=weights)


def _adam_chunk(
    model: AbstractModel,
    opt_state: Any,
    i: Array,
    n: Array,
    data: dict[str, Array],
    scales: tuple[Array, Array],
    key: Array,
    weights: Array | None,
    settings: AdamSettings,
    regularize: bool,
    stacked: bool = False,
) -> tuple[AbstractModel, Any, dict[str, Array]]:
    """Adam steps ``i, i + 1, …, i + n − 1`` (:func:`adam_step`; ``n ≥ 1``) in one program: a loop
    whose trip count ``n`` is an argument, so one compiled program serves every chunk length and
    each step is the same computation whatever the chunking. Returns the model and optimiser state
    after the last step and that step's loss terms, with ``"skipped"`` the count of skipped steps
    in the chunk. (Called once per step, the trainer spent 0.41 of a step's 0.94 ms in dispatch on
    ``steady_vortex``'s default plan: ``benchmarks/training_speed.py``.)

    ``stacked`` (static): the chunk of ``K`` members as one program (``jax.vmap``): ``model``,
    ``opt_state``, ``key`` ``(K, 2)`` and ``weights`` ``(K, P)`` (or None) hold the members'
    arrays stacked on a leading axis (:func:`stack`), and so do the outputs (each loss term
    ``(K,)``). The members share the data, the steps and the configuration; each draws its own
    minibatches from its own key and weights, as it would alone. ``settings`` is shared: the
    members' configurations are equal but for the seed."""
    if stacked:

        def member(m: AbstractModel, o: Any, k: Array, w: Array | None) -> tuple:
            return _adam_chunk(m, o, i, n, data, scales, k, w, settings, regularize)

        axes = (eqx.if_array(0), eqx.if_array(0), 0, eqx.if_array(0))
        return eqx.filter_vmap(member, in_axes=axes)(model, opt_state, key, weights)
    params, static = eqx.partition(model, eqx.is_array)

    def step(k: Array, p: Any, o: Any) -> tuple[Any, Any, dict[str, Array]]:
        model = eqx.combine(p, static)
        m, o, terms = _adam_step(model, o, i + k, data, scales, key, weights, settings, regularize)
        return eqx.filter(m, eqx.is_array), o, terms

    shapes = jax.eval_shape(step, jnp.asarray(0), params, opt_state)[2]
    terms0 = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)

    def body(k: Array, carry: tuple[Any, Any, dict[str, Array], Array]) -> tuple:
        p, o, _, skipped = carry
        p, o, terms = step(k, p, o)
        return p, o, terms, skipped + terms["skipped"]

    carry = (params, opt_state, terms0, jnp.zeros((), terms0["skipped"].dtype))
    params, opt_state, terms, skipped = jax.lax.fori_loop(0, n, body, carry)
    return eqx.combine(params, static), opt_state, {**terms, "skipped": skipped}


adam_chunk = eqx.filter_jit(_adam_chunk)


def stack(trees: list[Any]) -> Any:
    """The array leaves of same-structured ``trees`` stacked on a new leading axis (the other
    leaves taken from the first)."""
    return jax.tree.map(lambda *xs: jnp.stack(xs) if eqx.is_array(xs[0]) else xs[0], *trees)


def take(tree: Any, index: Any) -> Any:
    """``tree`` with every array leaf indexed by ``index`` on its leading axis: an int unstacks one
    member of :func:`stack`, an int array keeps those members."""
    return jax.tree.map(lambda x: x[index] if eqx.is_array(x) else x, tree)


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
    ``docs/benchmarks/training_speed*.txt``."""
    _adam_phase(trainers, states, callbacks, checkpoints, trainers[0].config.steps, checkpoint_seconds)
    return states


def _adam_phase(
    trainers: list[Trainer],
    states: list[TrainState],
    callbacks: list[Callable[[TrainState, dict[str, float]], None] | None],
    checkpoints: list[Callable[[TrainState], None] | None],
    until: int,
    checkpoint_seconds: float,
) -> None:
    """The Adam loop of :meth:`Trainer.run` (one member: :func:`adam_chunk` on its own arrays) and
    of :func:`run_together` (several: :func:`adam_chunk` on their stacked arrays), from the
    members' common ``state.step`` up to ``until``, in chunks of steps (:func:`adam_chunk_end`)
    between which it validates, checkpoints, reports progress and looks at the time budget; the
    states are updated in place."""
    cfg = trainers[0].config
    settings = AdamSettings.of(cfg)
    data, scales = trainers[0]._train, trainers[0].scales
    alone = len(trainers) == 1
    member = (lambda tree, pos: tree) if alone else take
    if alone:
        models, opts, keys = states[0].model, states[0].opt_state, trainers[0]._key
    else:
        models, opts = stack([s.model for s in states]), stack([s.opt_state for s in states])
        keys = jnp.stack([t._key for t in trainers])
    own = [t.window_weights for t in trainers]
    weights = None if own[0] is None else jnp.asarray(own[0] if alone else np.stack(own), float)
    skipped = jnp.asarray([s.skipped for s in states])  # (members,), also for one
    active = list(range(len(trainers)))
    saved = tick = time.monotonic()
    per_step = 0.0  # measured seconds per step (per chunk), for the chunks' length
    i = states[0].step
    while i < until:
        regularize = cfg.regularizes(i)
        left = min(trainers[j].deadline("adam") for j in active) - time.monotonic()
        end = adam_chunk_end(cfg, i, until, per_step, left)
        name = f"adam-{regularize}" if alone else f"adam-{regularize}-{len(active)}"
        lead = trainers[active[0]]
        first, before = name not in lead._programs, lead.started
        models, opts, last = lead._uncounted_first(
            name,
            adam_chunk,
            models,
            opts,
            jnp.asarray(i),
            jnp.asarray(end - i),
            data,
            scales,
            keys,
            weights,
            settings,
            regularize,
            not alone,
        )
        now = time.monotonic()
        for j in active:  # compilation is nobody's time; the rest is shared (alone: all its own)
            trainer = trainers[j]
            if first and trainer is not lead:
                trainer.started += lead.started - before
            trainer.started += 0.0 if first else (now - tick) * (1.0 - 1.0 / len(active))
        if not first:
            per_step = (now - tick) / (end - i)
        tick = now
        i = done = end
        skipped = skipped + last["skipped"]
        ended = []
        due = time.monotonic() - saved >= checkpoint_seconds
        for pos, j in enumerate(active):
            trainer, state = trainers[j], states[j]
            late = None if done == cfg.steps else trainer._over_budget("adam", done, cfg.steps, "Adam")
            if done % cfg.val_every == 0 or done == cfg.steps or late is not None:
                record = adam_record(settings, done - 1, member(last, pos), skipped[pos])
                skipped = skipped.at[pos].set(0.0)
                state.opt_state, state.skipped = member(opts, pos), 0.0
                if trainer._record(state, member(models, pos), record, callbacks[j], stop=cfg, late=late):
                    ended.append(pos)  # the Adam phase is over (see _record)
                saved = time.monotonic()
            elif due and checkpoints[j] is not None:
                state.model, state.opt_state = member(models, pos), member(opts, pos)
                state.step, state.skipped = done, float(skipped[pos])
                checkpoints[j](state)  # type: ignore[misc]
                saved = time.monotonic()
            trainer._tell("adam", done)  # after the record or checkpoint: progress that is saved
        if ended:
            active = [j for p, j in enumerate(active) if p not in ended]
            if not active:
                return
            keep = jnp.asarray([p for p in range(len(skipped)) if p not in ended], dtype=int)
            models, opts, keys, weights, skipped = (
                take(x, keep) for x in (models, opts, keys, weights, skipped)
            )
    for pos, j in enumerate(active):
        state = states[j]
        state.model, state.opt_state = member(models, pos), member(opts, pos)
        state.step, state.skipped = max(state.step, until), float(skipped[pos])


def adam_chunk_end(
    config: TrainConfig, i: int, until: int, per_step: float = 0.0, left: float = np.inf
) -> int:
    """Where the chunk of Adam steps starting at step ``i`` ends (exclusive): at the next multiple
    of :data:`ADAM_CHUNK` or of ``val_every`` (a validation), at ``until``, where the flow penalty
    is dropped (:meth:`TrainConfig.regularizes`: another program), after at most
    :data:`CHUNK_SECONDS` of steps taking ``per_step`` seconds each (0: unknown), and once the
    ``left`` seconds of the time budget are used (one step when they are, or when nothing is left)."""
    end = min(until, (i // ADAM_CHUNK + 1) * ADAM_CHUNK, (i // config.val_every + 1) * config.val_every)
    if left <= 0:
        end = i + 1
    elif per_step > 0:
        end = min(end, i + max(1, int(min(CHUNK_SECONDS, left) / per_step)))
    regularize = config.regularizes(i)
    return next((k for k in range(i + 1, end) if config.regularizes(k) != regularize), end)


def adam_record(settings: AdamSettings, i: int, terms: dict[str, Array], skipped: Array) -> dict[str, Any]:
    """The history record after Adam step ``i`` (0-based): the step count, the step's loss terms
    (``train_*``), the steps skipped since the previous record (non-finite loss), the learning
    rate and the penalty's weight at the step."""
    record: dict[str, Any] = {"step": i + 1}
    record.update({f"train_{k}": float(v) for k, v in terms.items() if k != "skipped"})
    record["skipped_steps"] = float(skipped)
    record["lr"] = float(settings.rate(jnp.asarray(i)))
    record["lambda_flow"] = float(settings.flow_weight(jnp.asarray(i)))
    return record


#: Leaves that are one learned constant each (FHNN's constant linear drag and, with
#: ``added_mass="constant"``, added masses): they step at ``lr_c_l`` times Adam's rate.
CONSTANT_LEAVES = ("c_l_raw", "mass_raw")


def _c_l_labels(params: Any) -> Any:
    """``"c_l"`` for a leaf named in :data:`CONSTANT_LEAVES`, ``"rest"`` for every other leaf of
    ``params``."""

    def label(path: tuple, leaf: Any) -> str:
        last = path[-1] if path else None
        return "c_l" if getattr(last, "name", None) in CONSTANT_LEAVES else "rest"

    return jax.tree_util.tree_map_with_path(label, params)


def strong_types(tree: Any) -> Any:
    """``tree`` with every weakly typed array leaf made strong (same dtype). optax's L-BFGS
    initialises its line-search info as weak scalars and returns them strong after one update, so
    without this the quasi-Newton step compiles twice per phase (measured: 7.8 s + 9.1 s for a
    width-32 model)."""
    return jax.tree.map(lambda x: jnp.asarray(x, dtype=x.dtype) if eqx.is_array(x) else x, tree)


def quasi_newton_objective(
    params: Any, static: Any, data: dict[str, Array], scales: tuple[Array, Array], config: TrainConfig
) -> Array:
    """The quasi-Newton phases' objective: the data loss (no regulariser) of
    ``combine(params, static)`` over the whole batch ``data``."""
    return data_loss(loss_terms(eqx.combine(params, static), data, scales), config)


@eqx.filter_jit
def quasi_newton_step(
    flat: Array,
    opt_state: Any,
    like: Any,
    static: Any,
    data: dict[str, Array],
    scales: tuple[Array, Array],
    config: TrainConfig,
) -> tuple[Array, Any, Array]:
    """One L-BFGS iteration (``config.lbfgs_memory`` pairs, zoom line search) on
    :func:`quasi_newton_objective`, with the parameters as one vector ``flat`` ``(P,)`` laid out
    as ``jax.flatten_util.ravel_pytree(like)`` lays out ``like`` (the parameters' pytree; only its
    structure, shapes and dtypes matter). On one vector each of the optimiser's operations (the
    two-loop recursion over the memory, the line search's updates) is one operation, not one per
    leaf of the model (30 for the FHNN): an iteration at 4,000 pairs took 7.27 against 10.93 ms on
    the 2-core CPU, its objective and gradient 4.79 ms (``benchmarks/lbfgs_overhead.py``)."""
    opt = optax.lbfgs(memory_size=config.lbfgs_memory)
    unravel = ravel_pytree(like)[1]

    def objective(f: Array) -> Array:
        return quasi_newton_objective(unravel(f), static, data, scales, config)

    value, grad = optax.value_and_grad_from_state(objective)(flat, state=opt_state)
    updates, opt_state = opt.update(grad, opt_state, flat, value=value, grad=grad, value_fn=objective)
    return optax.apply_updates(flat, updates), opt_state, value
