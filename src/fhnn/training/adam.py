"""The Adam phase: its settings as compiled arguments, the compiled step and chunk of steps, and
the loop that runs one run, or the members of an ensemble stacked, between validations."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.models.base import AbstractModel
from fhnn.training import losses
from fhnn.training.losses import DATA_TERMS, REGULARIZERS, term_weight
from fhnn.training.sampling import draw_batch
from fhnn.training.train_config import TrainConfig

if TYPE_CHECKING:
    from fhnn.training.trainer import Trainer, TrainState

Array = jax.Array

#: Adam steps run as one compiled program between the trainer's looks at the clock (at most; see
#: :func:`adam_chunk_end`), and the wall time a chunk should not exceed once a step's time is known
#: (so a time budget is still checked every half second with slow steps).
ADAM_CHUNK = 50
CHUNK_SECONDS = 0.5


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


# The compiled programs of training. They are module-level functions whose data, scales and keys
# are arguments (not closed-over constants), as are the Adam phase's numbers (:class:`AdamSettings`);
# what shapes a program (the batch size, the terms in the loss, the quasi-Newton configuration) is
# a static, hashable argument. So a program is traced once per shape and structure in a process,
# and the persistent compilation cache (:func:`fhnn.runtime.use_compilation_cache`) and the
# stored executables (:mod:`fhnn.executables`) serve it to later processes.


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
        terms = losses.loss_terms(m, batch, scales)
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
    per_step = 0.0  # timed seconds per step (per chunk), for the chunks' length
    measured: set[str] = set()
    i = states[0].step
    while i < until:
        regularize = cfg.regularizes(i)
        left = min(trainers[j].deadline("adam") for j in active) - time.monotonic()
        end = adam_chunk_end(cfg, i, until, per_step, left)
        name = f"adam-{regularize}" if alone else f"adam-{regularize}-{len(active)}"
        lead = trainers[active[0]]
        models, opts, last = lead._program(
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
        if name in measured:
            per_step = (now - tick) / (end - i)
        measured.add(name)  # a program's first chunk includes its compilation
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
