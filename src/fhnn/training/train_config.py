"""The training configuration, :class:`TrainConfig`: its defaults are what ``fhnn train`` trains
on noise-free data; a plan (:mod:`fhnn.training.plans`) or the data's properties change named fields."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.errors import ConfigError

Array = jax.Array


#: Validation loss at or below which the warm-up is kept and Adam skipped (``warmup_accept``).
#: After 400 warm-up iterations (width 32, data seeds 0 and 1) ``solid_body_vortex``, a flow the
#: linear far field explains, reaches 1.1e-8 and ``steady_vortex`` 0.15: the threshold sits two
#: decades above the first.
WARMUP_ACCEPT = 1e-6

#: The values of ``TrainConfig.shoot_drift``.
SHOOT_DRIFTS = ("free", "model")


@frozen_config
class TrainConfig(Config):
    """Optimisation settings; each field is documented below it."""

    config_name = "training"

    # The defaults are what ``fhnn train`` trains on noise-free data with recorded derivatives
    # (the ``auto`` plan; the measurements that chose them: docs/design/data/plan_selection.txt).
    # A plan (fhnn.training.plans.PLANS) or the data (plans.data_settings) change named fields.
    steps: int = 20000
    """Adam steps (0: quasi-Newton phases only)."""
    batch_size: int = 256
    """Transition pairs per step."""
    lr: float = 3e-3
    """Initial learning rate."""
    lr_boundaries: tuple[float, ...] = (0.4, 0.6, 0.8, 0.9)
    """Fractions of ``steps`` at which the rate is multiplied by ``lr_decay``."""
    lr_decay: float = 0.3
    """Factor at each boundary."""
    w_deriv: float = 1.0
    """Weight of the derivative loss."""
    # recorded derivatives make the one-step loss redundant on clean data and a noise amplifier
    # on noisy data; data without recorded derivatives turn it on (plans.data_settings)
    w_step: float = 0.0
    """Weight of the one-step loss."""
    # the flow penalty (formerly 1e-6, annealed) was within 2 % of none on the validation loss of
    # all five actuated scenarios, for 20-35 % of the training time
    lambda_flow: float = 0.0
    """Initial weight of the flow-smoothness term."""
    flow_anneal: float = 0.5
    """Fraction of the steps over which ``lambda_flow`` decays linearly to 0."""
    seed: int = 0
    """Seed of initialisation and batch order (and of the weights under ``bootstrap``)."""
    val_every: int = 500
    """Steps between validations (the best validation model is kept)."""
    val_pairs: int = 8192
    """At most this many validation pairs are used per validation."""
    warmup_steps: int = 400
    """Quasi-Newton iterations on the model's warm-up parameters before Adam."""
    # 20,000 Adam steps and a polish of 10,000 were chosen on the validation loss of data seed 0
    # and confirmed on seed 1: lower or tied on all six scenarios against 12,000 / 5,000
    # (docs/design/data/plan_selection.txt, G and K)
    lbfgs_steps: int = 10000
    """Quasi-Newton polish iterations after Adam (0: none)."""
    track_steps: int = 0
    """Levenberg–Marquardt iterations on the whole training tracks after Adam and the polish, from the
    best model so far (0: none; :mod:`fhnn.training.tracks`; only for models that name their
    :meth:`~fhnn.models.base.AbstractModel.track_parameters`)."""
    track_chord: int = 0
    """Chord steps after each whole-track iteration: further steps with that iteration's Jacobian
    and the gradient at the new point, each kept while it lowers the objective (0: none;
    :meth:`~fhnn.training.tracks.TrackFit.step`)."""
    track_whole: int = 0
    """How many of the last ``track_steps`` iterations free every parameter of the model
    (:meth:`~fhnn.models.base.AbstractModel.track_parameters` with ``whole``: both nets entire)
    and are solved matrix-free (:meth:`~fhnn.training.tracks.TrackFit.step_matrix_free`), at
    about 0.5 s per product on the own-data benchmark's 49 tracks (0: none)."""
    track_cg_steps: int = 40
    """Conjugate-gradient products per matrix-free iteration (``track_whole``)."""
    track_samples: int = 25_000
    """The most samples (tracks × their padded length) the whole-track fit holds, on the training
    tracks and on the validation tracks each; larger splits are cut into pieces and a seeded subset
    kept (:func:`~fhnn.training.tracks.track_pieces`), so an iteration's cost does not grow with the
    data."""
    # 4,000 pairs: validation loss 2.01e-9 against 1.995e-9 (solid_body_vortex) and 3.05e-7
    # against 3.18e-7 (steady_vortex) with 8,000, data seed 1, at ~0.64x the time
    lbfgs_pairs: int = 4000
    """Training pairs (a seeded subset) in the quasi-Newton phases."""
    lbfgs_memory: int = 100
    """Curvature pairs kept by L-BFGS."""
    warmup_accept: float = WARMUP_ACCEPT
    """What the warm-up's validation loss decides (0: nothing — Adam always follows the warm-up).
    Above 0, a warm-up whose validation loss is at or below it is kept and the Adam phase is skipped
    (the polish starts from the warm-up); a warm-up above it is discarded and Adam starts from the
    initial model. The decision is logged in the warm-up's last history record (``"warmup": "kept"``
    or ``"discarded"``)."""
    max_time: float = 0.0
    """Wall-clock budget [s] of the command that trains, compilation and every member of an ensemble
    included (0: none): :class:`~fhnn.training.budget.Budget`. A phase cut short by it says so in
    ``stopped``, and the next command continues it; it is the command's, so a resumed run may be given
    another."""
    stop_rising: int = 6
    """The Adam phase ends early once the validation loss has risen at this many validations in a row
    (0: never); the polish, if any, then starts from the best model, as it always does."""
    shoot: int = 0
    """Samples per example of the multi-step (multiple-shooting) loss on positions (0 or 2: off). With
    ``k ≥ 3`` every example is ``k`` consecutive samples of a trajectory, each with its own times: RK4
    from the first, one step per sample interval, and the predicted positions are compared with the
    observed ones at every later sample — a loss that needs neither recorded velocities nor
    derivatives (``fhnn train`` turns it on for data whose velocities were estimated)."""
    w_shoot: float = 1.0
    """Weight of the multi-step loss."""
    shoot_skip: int = 0
    """The multi-step windows start at this sample of a trajectory or later (on both splits): a
    smoother's velocity estimate at a trajectory's first samples sees one side of it only, and a
    window's prediction starts from it."""
    lbfgs_stride: int = 1
    """The quasi-Newton phases draw their ``lbfgs_pairs`` examples from the windows starting every
    ``lbfgs_stride`` samples (from ``shoot_skip``); with the multi-step loss, ``shoot − 1`` tiles each
    trajectory with windows that share only their end samples, so every interval of the data enters
    the polish once."""
    lr_c_l: float = 1.0
    """Multiplier of the learning rate of a constant linear drag (the FHNN's ``c_l_raw``; other models
    have none) and of constant added masses (``mass_raw``, with ``added_mass="constant"``), whose
    noisy gradients leave them near their initial values at the plain rate (design note
    ``docs/design/plans.md``)."""
    shoot_noise: tuple[float, float] = (0.0, 0.0)
    """``(σ_x [m], σ_v [m/s])``, the noise of the observed positions and the error of the estimated
    velocity a multi-step window starts from ((0, 0): not modelled). With ``σ_x > 0`` the multi-step
    loss weighs each window's position residuals ``r`` (per axis) by the inverse of their covariance
    under those errors, ``rᵀ (I + J P Jᵀ)⁻¹ r`` with ``J = [1, t]`` (a start error's drift, free
    flight over the window) and ``P = diag(1, σ_v²/σ_x²)``, so that the model gains nothing by damping
    a start error it cannot see."""
    shoot_drift: str = "free"
    """How a start error drifts in that weighting: ``"free"``, in free flight (``J = [1, t]`` per
    axis); ``"model"``, as the model itself carries it — ``J`` the window's predicted positions'
    derivatives with respect to its start state (forward mode, held fixed in the gradient;
    :func:`fhnn.models.base.start_error_weighted_by`); not the default (design note
    ``docs/design/plans.md``)."""
    bootstrap: bool = False
    """Train on a Bayesian bootstrap of the training trajectories drawn from the seed (each
    trajectory's windows weighted by its own random weight, see :func:`bootstrap_weights`; the
    validation split is left whole). ``fhnn train --seeds N`` sets it, so the spread of an ensemble's
    members holds the data's sampling noise as well as that of their initialisation and batch order."""

    def validate(self) -> None:
        check_positive(self, "batch_size", "lr", "lr_decay", "val_every", "val_pairs", "lbfgs_pairs")
        check_positive(self, "lbfgs_memory", "track_samples")
        check_nonnegative(self, "w_deriv", "w_step", "lambda_flow", "flow_anneal", "seed", "lbfgs_steps")
        check_nonnegative(self, "steps", "warmup_steps", "stop_rising", "shoot", "w_shoot", "shoot_skip")
        check_nonnegative(self, "track_steps", "track_chord", "track_whole")
        check_positive(self, "track_cg_steps")
        if self.track_whole > self.track_steps:
            raise ConfigError(
                f"training: track_whole ({self.track_whole}) counts among track_steps ({self.track_steps})"
                " and cannot exceed it"
            )
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
