"""The interface every model implements: a training objective and a rollout.

:class:`AbstractModel` is what training and evaluation see:

- :meth:`AbstractModel.loss_terms` (abstract) — the unweighted training loss terms on a batch of
  windows;
- :meth:`AbstractModel.rollout` — predicted states of a split's trajectories from their first
  state (and forcing), as a :class:`Rollout`; it picks the times and start states and marks
  non-finite predictions as diverged, and each kind implements the prediction itself in the
  abstract :meth:`AbstractModel.predict`.

Two kinds implement it. :class:`AbstractVectorField` — FHNN and every continuous baseline — is a
vector field ``ṡ = f(s, t, F_ext)``: ``model(state, t, force)`` takes one state ``(4,)`` [m, m,
m/s, m/s], a time ``t`` [s] and the known external force ``(2,)`` [N] and returns ``ṡ`` ``(4,)``
(batching is ``jax.vmap``); its loss is the derivative and one-step RK4 error and its rollout an
adaptive high-accuracy solve. Discrete models (DHN) subclass :class:`AbstractModel` directly and
roll themselves out step by step.
"""

from __future__ import annotations

import abc
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.data.dataset import Split, samples_until
from fhnn.executables import StoredProgram
from fhnn.physics.actuation import actuation_force, forcing, held_grid
from fhnn.physics.integrators import rk4_solve, rk4_solve_held, rk4_step, solve_forced_batch

Array = jax.Array

#: Default rollout tolerance; its real error is checked by a test against a 1000× tighter solve.
ROLLOUT_TOL = 1e-10
#: A rollout whose state exceeds this multiple of the largest initial-state component (at least
#: 1) has blown up; it stops there and is reported as diverged.
BLOW_UP = 1e3
#: The batched rollout, kept compiled on disk (:mod:`fhnn.executables`): a later process runs a
#: rollout of the same model structure and shapes untraced.
_SOLVE = StoredProgram(solve_forced_batch)
#: Step budget per sample interval: a rollout needing more (a stiff, e.g. LNN, model) counts as a
#: solver failure and is reported as diverged. Well-posed models take about one step per interval.
STEPS_PER_SAMPLE = 20


def start_error_weighted(resid: Array, t: Array, start_var: Array) -> Array:
    """A multi-step window's squared position residuals weighed by the inverse of their
    covariance when the window starts from a position and a velocity with errors.

    Per window and axis, with ``τ_k = t_k − t_0`` and ``J = [1, τ]`` (a start error's drift in free
    flight), the residuals ``r`` have covariance ``σ_x² (I + J P Jᵀ)``, ``P = diag(start_var)``, in
    the units of the position noise σ_x (any common scale of ``r`` only scales the result); their
    weighted square is
    ``rᵀ (I + J P Jᵀ)⁻¹ r = rᵀr − uᵀ (P⁻¹ + JᵀJ)⁻¹ u``, ``u = Jᵀr`` (Woodbury: a 2 × 2 solve).

    Args:
        resid: ``(B, W−1, 2)`` residuals at samples ``1 … W−1``.
        t: ``(B, W)`` sample times [s].
        start_var: ``(B, 2)`` variances of the start position (relative to the noise, usually
            1) and start velocity (relative, [1/s²]) errors; both > 0.

    Returns:
        ``(B, 2)``: the weighted square per window and axis over ``W − 1`` (so that zero start
        errors give the mean squared residual).
    """
    tau = t[:, 1:] - t[:, :1]
    jac = jnp.stack([jnp.ones_like(tau), tau], axis=-1)  # (B, W-1, 2)
    info = jnp.einsum("bki,bkj->bij", jac, jac) + jax.vmap(jnp.diag)(1.0 / start_var)
    u = jnp.einsum("bki,bka->bia", jac, resid)  # (B, 2 params, 2 axes)
    explained = jnp.einsum("bia,bia->ba", u, jnp.linalg.solve(info, u))
    return (jnp.sum(resid**2, axis=1) - explained) / resid.shape[1]


def start_error_weighted_by(resid: Array, jac: Array, start_var: Array) -> Array:
    """:func:`start_error_weighted` with the model's own sensitivity of the window's predicted
    positions to its start state in place of the free flight ``J = [1, τ]``: the drift of a start
    error as the model carries it (damped by the drag, turned by the flow), both axes together.

    Args:
        resid: ``(B, W−1, 2)`` residuals at samples ``1 … W−1`` [m, or any common scale of the
            position noise's units].
        jac: ``(B, W−1, 2, 4)`` the predicted positions' derivatives with respect to the start
            state ``(x, y, vx, vy)`` [1, s].
        start_var: ``(B, 4)`` variances of the start state's errors relative to the position
            noise (``1, 1, σ_v²/σ_x², σ_v²/σ_x²``); all > 0.

    Returns:
        ``(B,)``: the weighted square per window over ``2 (W − 1)`` (zero start errors: the mean
        squared residual).
    """
    flat_r = resid.reshape(resid.shape[0], -1)  # (B, 2(W-1))
    flat_j = jac.reshape(jac.shape[0], -1, jac.shape[-1])  # (B, 2(W-1), 4)
    info = jnp.einsum("bki,bkj->bij", flat_j, flat_j) + jax.vmap(jnp.diag)(1.0 / start_var)
    u = jnp.einsum("bki,bk->bi", flat_j, flat_r)
    explained = jnp.einsum("bi,bi->b", u, jnp.linalg.solve(info, u[..., None])[..., 0])
    return (jnp.sum(flat_r**2, axis=1) - explained) / flat_r.shape[1]


@dataclass(frozen=True)
class Rollout:
    """Predicted states ``(N, T, 4)`` at times ``t`` ``(T,)`` (or each trajectory's own, ``(N,
    T)``); ``ok`` ``(N,)`` false where diverged; ``mask`` ``(N, T)`` true at the samples that are
    real (``None``: all), false at a shorter trajectory's padding."""

    t: np.ndarray
    states: np.ndarray
    ok: np.ndarray
    mask: np.ndarray | None = None


class AbstractModel(eqx.Module):
    """A trainable model of a floating body's dynamics (see the module docstring)."""

    @abc.abstractmethod
    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        """Unweighted training loss terms on a batch of windows (docs/spec.md §5).

        ``batch``: ``s`` ``(B, W, 4)`` consecutive observed states at times ``t`` ``(B, W)``, their
        true derivatives ``deriv`` ``(B, W, 4)``, recorded forces ``forces`` ``(B, W, 2)`` [N],
        forcing parameters ``act`` ``(B, 2, 3, 3)`` and the recorded forces less their sinusoids
        ``dforce`` ``(B, W, 2)`` (the force at any time inside the window is
        :func:`~fhnn.physics.actuation.forcing`), trajectory index ``traj`` ``(B,)``, a PRNG ``key``.
        ``scales``: per-component std of derivatives and of one-step increments ``(4,)`` each.
        Terms named in the trainer's ``REGULARIZERS`` are weighted by the annealed ``λ_flow``.
        """

    def rollout(
        self,
        split: Split,
        until: float | None = None,
        *,
        rtol: float = ROLLOUT_TOL,
        atol: float = ROLLOUT_TOL,
        from_clean: bool = True,
    ) -> Rollout:
        """Predict every trajectory of ``split`` from its start up to ``until`` [s] (default: the
        trajectories' end) with the trajectory's own forcing (:meth:`predict`). ``rtol``, ``atol``:
        tolerances of an adaptive solver (unused by discrete models); ``from_clean``: start from
        the clean states (docs/spec.md §5) rather than the observed ones. A trajectory with a non-finite
        prediction at one of its real samples is marked diverged. On irregular data each
        trajectory is predicted at its own times, up to the last of them at most ``until`` after
        its start."""
        times, counts = split.times, split.sample_counts
        if until is not None:
            counts = np.minimum(counts, [samples_until(row - row[0], until) for row in times])
        size = int(counts.max())
        t = split.t[..., :size]
        mask = np.arange(size)[None, :] < counts[:, None]
        start = split.states_clean if from_clean else split.states
        states, ok = self.predict(start, split, np.asarray(t), rtol, atol)
        states = np.asarray(states)
        finite = np.all(np.isfinite(states) | ~mask[..., None], axis=(1, 2))
        return Rollout(
            t=np.asarray(t),
            states=states,
            ok=np.asarray(ok) & finite,
            mask=None if split.regular else mask,
        )

    @abc.abstractmethod
    def predict(
        self, start: np.ndarray, split: Split, t: np.ndarray, rtol: float, atol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """States ``(N, T, 4)`` at the times ``t`` ``(T,)`` or ``(N, T)`` and ``ok`` ``(N,)`` (false
        where the prediction failed) for the trajectories of ``split``; ``start`` ``(N, ≥T, 4)`` holds the
        states a model may start from (a continuous model takes ``start[:, 0]``)."""

    def warmup(self) -> tuple[AbstractModel, Callable[[AbstractModel], AbstractModel]] | None:
        """What the trainer's warm-up phase fits first: ``(part, restore)``, a model whose every
        parameter trains during the warm-up and ``restore(fitted_part)``, the full model to go on
        with; ``None`` (default): no warm-up, every parameter trains from the start."""
        return None

    @property
    def window(self) -> int:
        """Consecutive samples per training example (2: a transition pair)."""
        return 2

    def track_parameters(self, whole: bool = False) -> Any:
        """The parameters the whole-track fit (:mod:`fhnn.training.tracks`) moves: a filter tree of
        ``self`` (true at the leaves that move); with ``whole``, those of its matrix-free
        iterations (``train.track_whole``), which may be every parameter. ``None`` (default): the
        model has no whole-track fit, and the phase is skipped."""
        return None

    def quasi_newton_weights(self, batch: dict[str, Array]) -> Array | None:
        """Weights ``(B,)`` (mean 1) of the windows of ``batch`` in the trainer's quasi-Newton
        phases, computed once from the model a phase starts from and held fixed through it;
        ``None`` (default): every window alike."""
        return None


class AbstractVectorField(AbstractModel):
    """A learned (or known) vector field ``ṡ = f(s, t, F_ext)``."""

    @abc.abstractmethod
    def __call__(self, state: Array, t: Array, force: Array) -> Array:
        """``ṡ`` (shape ``(4,)``) at ``state`` (``(4,)``), time ``t`` [s], force ``(2,)`` [N]."""

    def regularization(self, states: Array, ts: Array) -> dict[str, Array]:
        """Extra loss terms (unweighted), evaluated at a batch of states ``(B, 4)`` and times ``(B,)``."""
        return {}

    def loss_terms(self, batch: dict[str, Array], scales: tuple[Array, Array]) -> dict[str, Array]:
        """``{"deriv": MSE of f(s_0) against the true derivative, "step": MSE of one RK4 step
        against s_1}`` (both normalised by ``scales``) plus :meth:`regularization`; on windows of
        ``W ≥ 3`` samples also ``"shoot"``: RK4 from ``s_0`` through every sample time of the
        window, the MSE of the predicted positions at samples ``1 … W−1`` (normalised by the
        positions' one-step scale) — weighed by the inverse of its covariance under the window's
        start errors where the batch holds ``"start_var"`` (:func:`start_error_weighted`). Where
        the batch holds ``"weight"`` ``(B,)`` (mean 1), each term is that weighted mean over the
        windows."""
        deriv_scale, step_scale = scales
        width = batch["s"].shape[1]

        # the model's own start sensitivity where the batch's start errors are given per state
        # component (start_error_weighted_by), the free flight's where per axis
        sensitive = width > 2 and batch.get("start_var") is not None and batch["start_var"].shape[-1] == 4

        held = "switch" in batch  # held forcing: RK4 steps split where the force changes

        def one(s: Array, t: Array, a: Array, r: Array, sw: Array) -> tuple[Array, Array, Array | None]:
            f = lambda x, tt: self(x, tt, forcing(a, tt, t, r))  # noqa: E731
            d0 = f(s[0], t[0])
            if held:
                fu = lambda x, tt, u: self(x, tt, actuation_force(a, tt) + u)  # noqa: E731
                solve = lambda x: rk4_solve_held(fu, x, t, r, sw)  # noqa: E731
            elif width == 2:
                return d0, rk4_step(f, s[0], t[0], t[1] - t[0], k1=d0)[None], None
            else:
                solve = lambda x: rk4_solve(f, x, t)  # noqa: E731
            path = solve(s[0])[1:]
            if not sensitive:
                return d0, path, None
            # held fixed in the gradient: the weights of generalised least squares, not a term
            jac = jax.jacfwd(lambda x: solve(x)[1:, :2])(jax.lax.stop_gradient(s[0]))
            return d0, path, jax.lax.stop_gradient(jac)

        switch = batch["switch"] if held else batch["t"]  # unread where the forcing is interpolated
        pred_d, pred_path, start_jac = jax.vmap(one)(
            batch["s"], batch["t"], batch["act"], batch["dforce"], switch
        )
        weight = batch.get("weight")
        if weight is None:
            mean = jnp.mean
        else:  # per-window weights (B,) of mean 1: a weighted mean over the windows

            def mean(x: Array) -> Array:
                return jnp.mean(weight * jnp.mean(x.reshape(x.shape[0], -1), axis=1))

        terms = {
            "deriv": mean(((pred_d - batch["deriv"][:, 0]) / deriv_scale) ** 2),
            "step": mean(((pred_path[:, 0] - batch["s"][:, 1]) / step_scale) ** 2),
        }
        if width > 2:
            metres = pred_path[..., :2] - batch["s"][:, 1:, :2]
            resid = metres / step_scale[:2]
            if sensitive:  # in metres, then in the scaled units on average over the axes
                resid_sq = start_error_weighted_by(metres, start_jac, batch["start_var"])
                resid_sq = resid_sq / jnp.mean(step_scale[:2] ** 2)
            elif "start_var" in batch:
                resid_sq = start_error_weighted(resid, batch["t"], batch["start_var"])
            else:
                resid_sq = resid**2
            terms["shoot"] = mean(resid_sq)
        terms.update(self.regularization(batch["s"][:, 0], batch["t"][:, 0]))
        return terms

    def predict(
        self, start: np.ndarray, split: Split, t: np.ndarray, rtol: float, atol: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Adaptive Dopri8 from ``start[:, 0]`` whose steps land on every sample time (no
        interpolation error) and, under held forcing, on each change of the force
        (:func:`~fhnn.physics.actuation.held_grid`). A state beyond :data:`BLOW_UP` times the
        initial scale, or running out of :data:`STEPS_PER_SAMPLE` steps per interval, fails the
        trajectory."""
        size = t.shape[-1]
        residual = split.force_residual[:, :size]
        if split.switch is None:
            return self.solve(start[:, 0], t, split.actuation, residual, rtol, atol)
        times = np.broadcast_to(t, (split.n_traj, size))
        grid, values, picks = held_grid(times, residual, split.switch[:, :size])
        states, ok = self.solve(start[:, 0], grid, split.actuation, values, rtol, atol)
        return np.take_along_axis(states, picks[..., None], axis=1), ok

    def solve(
        self,
        y0: np.ndarray,
        t: np.ndarray,
        actuation: np.ndarray,
        residual: np.ndarray,
        rtol: float = ROLLOUT_TOL,
        atol: float = ROLLOUT_TOL,
    ) -> tuple[np.ndarray, np.ndarray]:
        """States ``(N, T, 4)`` at the times ``t`` ``(T,)`` or ``(N, T)`` from ``y0`` ``(N, 4)`` at
        ``t[..., 0]``, under the sinusoids ``actuation`` ``(N, 2, 3, 3)`` plus the linear
        interpolant of ``residual`` ``(N, T, 2)`` [N] (:func:`~fhnn.physics.actuation.forcing`),
        and ``ok`` ``(N,)``: adaptive Dopri8 landing on every time; a state beyond
        :data:`BLOW_UP` times the initial scale, or running out of :data:`STEPS_PER_SAMPLE` steps
        per interval, fails the trajectory."""
        max_steps = STEPS_PER_SAMPLE * (t.shape[-1] - 1) + 1000
        bound = jnp.asarray(BLOW_UP * max(1.0, float(np.max(np.abs(y0)))))
        ys, ok = _SOLVE(
            self,
            jnp.asarray(y0),
            jnp.asarray(actuation),
            jnp.asarray(t),
            rtol,
            atol,
            max_steps,
            bound,
            jnp.asarray(residual),
        )
        return np.asarray(ys), np.asarray(ok)
