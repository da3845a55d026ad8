"""Training of any :class:`~fhnn.models.base.AbstractVectorField` on a data set (SPEC §5).

Loss ``L = w_deriv L_deriv + w_step L_step + λ_flow(step) L_flow``:

- ``L_deriv``: MSE of ``f(s, t, F(t))`` against the stored true derivatives, per component divided
  by the training set's standard deviation of that component (so positions, velocities and
  accelerations weigh alike);
- ``L_step``: MSE of one RK4 step over ``dt`` (with the exact forcing ``F(t)`` inside the step)
  against the next observed state, per component divided by the std of the observed increments;
- ``L_flow``: the model's regularisation (FHNN: mean ``‖Hψ‖²_F`` at the batch positions). Its
  weight anneals linearly from ``lambda_flow`` to 0 over the first ``flow_anneal`` fraction of the
  steps, so its bias towards zero-curvature flows (a vortex has curvature) is gone by the end.

Adam with a piecewise-constant learning rate (×``lr_decay`` at each fraction in ``lr_boundaries``),
minibatches drawn from ``jax.random.fold_in(key, step)`` so that a resumed run draws the same
batches as an uninterrupted one. Optionally a final full-batch L-BFGS polish (``lbfgs_steps``
iterations on a fixed, seeded subset of ``lbfgs_pairs`` pairs, derivative and step losses only)
from the best Adam model: in float64 it lowers the loss where Adam's noise floor stops (measured on
``steady_vortex``: RMSE(pos) at 5 s 1.4e-4 → 7.9e-5 m after 600 iterations on 16k pairs). The phase
is deterministic; a run interrupted inside it restarts the phase from the Adam checkpoint.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.config import Config, check_nonnegative, check_positive, frozen_config
from fhnn.data.dataset import Split
from fhnn.errors import ConfigError
from fhnn.models.base import AbstractVectorField
from fhnn.physics.actuation import actuation_force
from fhnn.physics.integrators import rk4_step

Array = jax.Array


@frozen_config
class TrainConfig(Config):
    """Optimisation settings.

    Attributes:
        steps: optimiser steps.
        batch_size: transition pairs per step.
        lr: initial learning rate.
        lr_boundaries: fractions of ``steps`` at which the rate is multiplied by ``lr_decay``.
        lr_decay: factor at each boundary.
        w_deriv, w_step: weights of the derivative and one-step losses.
        lambda_flow: initial weight of the flow-smoothness term.
        flow_anneal: fraction of the steps over which ``lambda_flow`` decays linearly to 0.
        seed: seed of initialisation and batch order.
        val_every: steps between validations (the best validation model is kept).
        val_pairs: at most this many validation pairs are used per validation.
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
    lbfgs_steps: int = 0
    lbfgs_pairs: int = 8192

    def validate(self) -> None:
        check_positive(self, "steps", "batch_size", "lr", "lr_decay", "val_every", "val_pairs", "lbfgs_pairs")
        check_nonnegative(self, "w_deriv", "w_step", "lambda_flow", "flow_anneal", "seed", "lbfgs_steps")
        if any(not 0 < b < 1 for b in self.lr_boundaries):
            raise ConfigError(f"training: lr_boundaries must lie in (0, 1), got {self.lr_boundaries}")

    def schedule(self) -> optax.Schedule:
        bounds = {int(b * self.steps): self.lr_decay for b in self.lr_boundaries}
        # optax multiplies at each boundary; equal boundaries would collapse into one key
        return optax.piecewise_constant_schedule(self.lr, bounds)

    def flow_weight(self, step: Array) -> Array:
        if self.flow_anneal <= 0:
            return jnp.asarray(0.0)
        frac = step / (self.flow_anneal * self.steps)
        return self.lambda_flow * jnp.clip(1.0 - frac, 0.0, 1.0)


@dataclass(frozen=True)
class Pairs:
    """Transition pairs of a split: ``(s_k, t_k, s_{k+1})`` with forcing and true derivatives.

    Shapes: ``s``, ``s_next``, ``deriv`` ``(P, 4)``; ``t``, ``dt`` ``(P,)``; ``act`` ``(P, 2, 3, 3)``.
    """

    s: np.ndarray
    t: np.ndarray
    dt: np.ndarray
    s_next: np.ndarray
    deriv: np.ndarray
    act: np.ndarray

    @classmethod
    def of(cls, split: Split) -> Pairs:
        n, T = split.n_traj, split.n_times
        s = split.states[:, :-1].reshape(-1, 4)
        s_next = split.states[:, 1:].reshape(-1, 4)
        t = np.broadcast_to(split.t[:-1], (n, T - 1)).reshape(-1)
        dt = np.broadcast_to(np.diff(split.t), (n, T - 1)).reshape(-1)
        deriv = split.derivs[:, :-1].reshape(-1, 4)
        act = np.repeat(split.actuation, T - 1, axis=0)
        return cls(s=s, t=t, dt=dt, s_next=s_next, deriv=deriv, act=act)

    def __len__(self) -> int:
        return int(self.s.shape[0])

    def subset(self, idx: np.ndarray) -> Pairs:
        return Pairs(*(getattr(self, k)[idx] for k in ("s", "t", "dt", "s_next", "deriv", "act")))

    def as_jax(self) -> dict[str, Array]:
        return {k: jnp.asarray(getattr(self, k)) for k in ("s", "t", "dt", "s_next", "deriv", "act")}


@dataclass(frozen=True)
class LossScales:
    """Per-component scales of the derivative and step residuals (from the training split)."""

    deriv: np.ndarray
    step: np.ndarray

    @classmethod
    def of(cls, pairs: Pairs) -> LossScales:
        floor = lambda x: np.maximum(x, 1e-12)  # noqa: E731
        return cls(deriv=floor(pairs.deriv.std(axis=0)), step=floor((pairs.s_next - pairs.s).std(axis=0)))


def loss_terms(
    model: AbstractVectorField, batch: dict[str, Array], scales: tuple[Array, Array]
) -> dict[str, Array]:
    """The unweighted loss terms ``{"deriv", "step", <regularisation>}`` on a batch of pairs."""
    deriv_scale, step_scale = scales

    def one(s: Array, t: Array, dt: Array, a: Array) -> tuple[Array, Array]:
        f = lambda x, tt: model(x, tt, actuation_force(a, tt))  # noqa: E731
        return f(s, t), rk4_step(f, s, t, dt)

    pred_d, pred_next = jax.vmap(one)(batch["s"], batch["t"], batch["dt"], batch["act"])
    terms = {
        "deriv": jnp.mean(((pred_d - batch["deriv"]) / deriv_scale) ** 2),
        "step": jnp.mean(((pred_next - batch["s_next"]) / step_scale) ** 2),
    }
    terms.update(model.regularization(batch["s"], batch["t"]))
    return terms


@dataclass
class TrainState:
    """Everything needed to continue training: model, optimiser state, step, best model, history."""

    model: AbstractVectorField
    opt_state: Any
    step: int
    best_model: AbstractVectorField
    best_val: float
    history: list[dict[str, float]]


class Trainer:
    """Trains a model on the train split, validating on the val split."""

    def __init__(self, config: TrainConfig, train: Split, val: Split) -> None:
        self.config = config
        self.train_pairs = Pairs.of(train)
        val_pairs = Pairs.of(val)
        if len(val_pairs) > config.val_pairs:
            idx = np.random.default_rng(config.seed).choice(len(val_pairs), config.val_pairs, replace=False)
            val_pairs = val_pairs.subset(np.sort(idx))
        self.val_pairs = val_pairs
        sc = LossScales.of(self.train_pairs)
        self.scales = (jnp.asarray(sc.deriv), jnp.asarray(sc.step))
        self.optimizer = self.optimizer_for(config)
        self._train = self.train_pairs.as_jax()
        self._val = self.val_pairs.as_jax()
        self._key = jax.random.PRNGKey(config.seed + 1)
        self._step_fn = self._make_step()
        self._val_fn = eqx.filter_jit(lambda m: loss_terms(m, self._val, self.scales))

    @property
    def total_steps(self) -> int:
        """Adam steps plus L-BFGS iterations."""
        return self.config.steps + self.config.lbfgs_steps

    def polish(
        self, state: TrainState, callback: Callable[[TrainState, dict[str, float]], None] | None = None
    ) -> TrainState:
        """Full-batch L-BFGS from the best model on a seeded subset of the training pairs."""
        cfg = self.config
        n = min(cfg.lbfgs_pairs, len(self.train_pairs))
        idx = np.sort(np.random.default_rng(cfg.seed + 2).choice(len(self.train_pairs), n, replace=False))
        batch = self.train_pairs.subset(idx).as_jax()
        params, static = eqx.partition(state.best_model, eqx.is_array)
        scales = self.scales

        def objective(p: Any) -> Array:
            terms = loss_terms(eqx.combine(p, static), batch, scales)
            return cfg.w_deriv * terms["deriv"] + cfg.w_step * terms["step"]

        opt = optax.lbfgs()
        value_and_grad = optax.value_and_grad_from_state(objective)

        @jax.jit
        def step(p: Any, s: Any) -> tuple[Any, Any, Array]:
            value, grad = value_and_grad(p, state=s)
            updates, s = opt.update(grad, s, p, value=value, grad=grad, value_fn=objective)
            return optax.apply_updates(p, updates), s, value

        opt_state = opt.init(params)
        every = max(1, min(cfg.val_every, cfg.lbfgs_steps // 5 or 1))
        for k in range(cfg.lbfgs_steps):
            params, opt_state, value = step(params, opt_state)
            done = k + 1
            if done % every == 0 or done == cfg.lbfgs_steps:
                model = eqx.combine(params, static)
                val = self.validate(model)
                record = {"step": cfg.steps + done, "train_loss": float(value), "phase": "lbfgs"}
                record.update({f"val_{key}": v for key, v in val.items()})
                state.history.append(record)
                if val["deriv"] + val["step"] < state.best_val:
                    state.best_val, state.best_model = val["deriv"] + val["step"], model
                state.model, state.step = model, cfg.steps + done
                if callback is not None:
                    callback(state, record)
        return state

    @staticmethod
    def optimizer_for(config: TrainConfig) -> optax.GradientTransformation:
        """Adam with the configuration's piecewise-constant learning rate."""
        return optax.adam(config.schedule())

    def _make_step(self) -> Callable:
        cfg, optimizer, data, scales, key = self.config, self.optimizer, self._train, self.scales, self._key
        n = len(self.train_pairs)

        @eqx.filter_jit
        def step(model: AbstractVectorField, opt_state: Any, i: Array) -> tuple[Any, Any, dict[str, Array]]:
            idx = jax.random.randint(jax.random.fold_in(key, i), (cfg.batch_size,), 0, n)
            batch = {k: v[idx] for k, v in data.items()}
            weight = cfg.flow_weight(i)

            def total(m: AbstractVectorField) -> tuple[Array, dict[str, Array]]:
                terms = loss_terms(m, batch, scales)
                reg = sum((v for k, v in terms.items() if k not in ("deriv", "step")), jnp.zeros(()))
                loss = cfg.w_deriv * terms["deriv"] + cfg.w_step * terms["step"] + weight * reg
                return loss, {**terms, "loss": loss}

            grads, terms = eqx.filter_grad(total, has_aux=True)(model)
            updates, opt_state = optimizer.update(grads, opt_state, eqx.filter(model, eqx.is_array))
            return eqx.apply_updates(model, updates), opt_state, terms

        return step

    def init(self, model: AbstractVectorField) -> TrainState:
        opt_state = self.optimizer.init(eqx.filter(model, eqx.is_array))
        return TrainState(
            model=model, opt_state=opt_state, step=0, best_model=model, best_val=np.inf, history=[]
        )

    def validate(self, model: AbstractVectorField) -> dict[str, float]:
        terms = self._val_fn(model)
        return {k: float(v) for k, v in terms.items()}

    def run(
        self,
        state: TrainState,
        *,
        until: int | None = None,
        callback: Callable[[TrainState, dict[str, float]], None] | None = None,
    ) -> TrainState:
        """Train from ``state.step`` up to ``until`` (default: ``config.steps``)."""
        cfg = self.config
        until = cfg.steps if until is None else min(until, cfg.steps)
        model, opt_state = state.model, state.opt_state
        last: dict[str, Array] = {}
        for i in range(state.step, until):
            model, opt_state, last = self._step_fn(model, opt_state, jnp.asarray(i))
            done = i + 1
            if done % cfg.val_every == 0 or done == cfg.steps:
                val = self.validate(model)
                val_total = val["deriv"] + val["step"]
                record = {"step": done, **{f"train_{k}": float(v) for k, v in last.items()}}
                record.update({f"val_{k}": v for k, v in val.items()})
                record["lr"] = float(cfg.schedule()(i))
                record["lambda_flow"] = float(cfg.flow_weight(jnp.asarray(i)))
                state.history.append(record)
                if val_total < state.best_val:
                    state.best_val, state.best_model = val_total, model
                state.model, state.opt_state, state.step = model, opt_state, done
                if callback is not None:
                    callback(state, record)
        state.model, state.opt_state, state.step = model, opt_state, max(state.step, until)
        return state
