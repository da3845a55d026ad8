"""Does training on longer windows settle the drag split? Continuations of ``own_data.py``'s run.

``fhnn train`` fits issue 14's positions on windows of 40 samples (2 s), which hold little on the
split between ``c_l`` and ``c_q`` (``benchmarks/own_data_bound.py --window``: ``c_l``'s bound is
several percent there, under 1 % on windows of 160). This script starts from the defaults' trained
run (``benchmarks/own_data.py --data-seed K`` in ``--out``) and goes on training it on longer
windows, each continuation on its own:

- ``adam:W:B:STEPS:DRIFT`` — Adam on windows of ``W`` samples in batches of ``B`` for ``STEPS``
  steps at ``--lr`` (the run's own schedule shape, ``c_l`` at its 10× rate, no flow penalty), the
  start errors weighed with ``train.shoot_drift=DRIFT`` (``free`` or ``model``);
- ``lbfgs:ITERATIONS:PARTS:W:DRIFT`` — L-BFGS (memory 20), full batch, on all parameters
  (``PARTS`` ``all``) or the coefficients only (``coef``), on windows of ``W`` samples starting
  every ``W/4`` samples (``W`` 0: every training track as one window from its first sample, as
  long as the shortest track), the start errors weighed with ``train.shoot_drift=DRIFT``;
- ``tracks:ITERATIONS`` — whole training tracks by maximum likelihood (variable projection): each
  track's start state is a free parameter, refitted by Gauss–Newton (two steps per evaluation,
  warm-started, held fixed in the gradient: at its optimum the gradient in the model's parameters
  is the reduced objective's), and L-BFGS (memory 20) moves all the model's parameters,
  Jacobi-preconditioned by the diagonal of the Gauss–Newton matrix ``JᵀJ`` (16 Hutchinson
  probes); the objective is the mean square position residual per axis [m²], RK4 one step per
  sample interval. ``tracks:ITERATIONS:C_L`` holds the linear drag at ``C_L`` [N·s/m] (a point of
  its profile likelihood: everything else refitted with it).
- ``known-flow:ITERATIONS:FROM[:C_L]`` — the same whole-track fit with the simulator's true flow
  in the model's place and held: only the coefficients move (``C_L`` as above). ``FROM`` is where
  the coefficients start: ``run`` the defaults' run's, ``truth`` the coefficient net regressed onto
  the true laws at the visited (r, σ) points (raw outputs, 4,000 Adam steps) with ``c_l`` the true
  value. With the flow's error out of the way, what is left is the likelihood along the drag split.
- ``known-flow-lm:ITERATIONS:FROM`` — the same, fitted by the library's whole-track
  Levenberg–Marquardt (:class:`fhnn.training.tracks.TrackFit`, ``fhnn train``'s
  ``train.track_steps`` phase) on the coefficient net's output layer and ``c_l``.

For each it prints the 2 s windows' training and validation loss (``fhnn train``'s own objective,
on every training window and on the validation windows), the recovery against the simulator's
truth (masses, ``c_q``, ``c_l`` mean relative error; ``c_q``'s largest error per σ band) and the
flow's relative L2 error, before and after.

Usage::

    python benchmarks/own_data_longer_windows.py [--out benchmarks/_own_data] [--data-seed 0]
        [--lr 1e-3] RUN [RUN ...]

e.g. ``adam:80:16:2000:free adam:160:8:2000:model lbfgs:100:all:0:free tracks:200
known-flow:100:truth:3.0``. After a ``tracks`` or ``known-flow`` run it also prints the whole-track
misfit (``own_data_truth_loss.py --tracks``) of the start, of the continued model, of its flow with
the true coefficients and of the truth.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree
from own_data import recovery_scores, trained_run
from own_data_truth_loss import scored_models, track_misfit

from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery, visited_r_sigma
from fhnn.models.fhnn import uncap
from fhnn.physics.actuation import forcing
from fhnn.physics.integrators import rk4_solve
from fhnn.training.tracks import TrackFit
from fhnn.training.trainer import (
    QUASI_NEWTON_FIELDS,
    Trainer,
    data_loss,
    loss_terms,
    quasi_newton_step,
    strong_types,
)

#: ``loss_terms`` compiled once for every model the script scores.
_terms = eqx.filter_jit(loss_terms)


def score(model, base: Trainer, train: dict, scored) -> str:
    """One line: ``model``'s 2 s training and validation loss and its recovery."""
    tr = float(data_loss(_terms(model, train, base.scales), base.config))
    va = base.validate(model)["total"]
    rec = recovery_scores(coefficient_recovery(model.coefficients, scored))
    c = rec["coefficients_mean_rel"]
    bands = " ".join(f"{b['c_q']:.1%}" for b in rec["c_q_by_sigma"])
    flow = flow_recovery(model.flow, scored)["rel_l2"]
    return (
        f"2 s loss train {tr:.9g} val {va:.9g} | m_ax {c['m_ax']:.2%} m_ay {c['m_ay']:.2%} "
        f"c_q {c['c_q']:.2%} c_l {c['c_l']:.2%} flow {flow:.2%} | c_q per σ band {bands}"
    )


def adam(model, imported, base: Trainer, window: int, batch: int, steps: int, drift: str, lr: float):
    """``model`` after ``steps`` Adam steps on windows of ``window`` samples (its last iterate)."""
    cfg = dataclasses.replace(
        base.config,
        shoot=window,
        batch_size=batch,
        steps=steps,
        lr=lr,
        lambda_flow=0.0,
        val_every=max(100, steps // 5),
        shoot_drift=drift,
    )
    trainer = Trainer(cfg, imported.train, imported.val, window=window)

    def tell(_, record: dict) -> None:
        print(f"    step {record['step']}: validation loss ({window} samples) {record['val_total']:.6g}")

    return trainer.run(trainer.init(model), callback=tell).model


def _free(model, parts: str):
    """The filter of ``model``'s leaves an optimiser moves: every array (``parts`` ``all``) or the
    coefficients' only (``coef``)."""
    free = jax.tree.map(eqx.is_array, model)
    if parts == "all":
        return free
    fixed = jax.tree.map(lambda _: False, model)
    return eqx.tree_at(lambda m: m.eom.coefficients, fixed, replace=free.eom.coefficients)


def lbfgs(model, imported, base: Trainer, iterations: int, parts: str, window: int, drift: str):
    """``model`` after ``iterations`` L-BFGS steps on windows of ``window`` samples every
    ``window // 4`` (0: the whole training tracks)."""
    cfg = base.config
    whole = window == 0
    if whole:
        window = int(imported.train.sample_counts.min()) - cfg.first_start
    cfg = dataclasses.replace(cfg, shoot=window, shoot_drift=drift)
    trainer = Trainer(cfg, imported.train, imported.val, window=window)
    offset = trainer.train_pairs.start - cfg.first_start
    pool = np.flatnonzero(offset == 0 if whole else offset % max(1, window // 4) == 0)
    batch = trainer.batch(trainer.train_pairs.subset(pool))
    params, static = eqx.partition(model, _free(model, parts))
    flat, unravel = ravel_pytree(params)
    qn = dataclasses.replace(cfg.only(QUASI_NEWTON_FIELDS), lbfgs_memory=20)
    opt_state = strong_types(optax.lbfgs(memory_size=20).init(flat))
    for k in range(iterations):
        flat, opt_state, value = quasi_newton_step(flat, opt_state, params, static, batch, trainer.scales, qn)
        if (k + 1) % max(1, iterations // 5) == 0:
            what = f"{len(pool)} windows of {window} samples"
            print(f"    iteration {k + 1}: objective ({what}) {float(value):.6g}")
    return eqx.combine(unravel(flat), static)


def tracks(model, imported, iterations: int, c_l: float | None = None, parts: str = "all"):
    """``model`` after ``iterations`` L-BFGS steps on the whole training tracks, each track's
    start state fitted alongside (see the module docstring); ``c_l`` [N·s/m]: the linear drag held
    at that value (``None``: fitted too); ``parts``: ``all`` the model's parameters move, ``coef``
    the coefficients' only (the flow held)."""
    sp = imported.train
    t, obs = jnp.asarray(sp.times), jnp.asarray(sp.states[..., :2])
    mask, act, res = jnp.asarray(sp.mask), jnp.asarray(sp.actuation), jnp.asarray(sp.force_residual)
    n = 2 * float(mask.sum())

    def track_resid(m, s0, tt, aa, rr, mk, ob):
        """One track's masked position residuals ``(T, 2)`` [m] from start state ``s0``."""
        f = lambda x, ti: m(x, ti, forcing(aa, ti, tt, rr))  # noqa: E731
        return jnp.where(mk[:, None], rk4_solve(f, s0, tt)[:, :2] - ob, 0.0)

    def resid(m, z):
        return jax.vmap(lambda s0, *track: track_resid(m, s0, *track))(z, t, act, res, mask, obs)

    def gauss_newton(m, z):
        """One Gauss–Newton step on every track's start state."""

        def one(s0, *track):
            r = lambda s: track_resid(m, s, *track).ravel()  # noqa: E731
            j = jax.jacfwd(r)(s0)
            h = j.T @ j
            return s0 - jnp.linalg.solve(h + 1e-9 * jnp.trace(h) * jnp.eye(4), j.T @ r(s0))

        return jax.vmap(one)(z, t, act, res, mask, obs)

    free = _free(model, parts)
    if c_l is not None:
        coef = model.eom.coefficients
        raw = uncap(np.asarray(c_l), np.asarray(coef.caps[3]), coef.cap_map)
        model = eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, model, jnp.asarray(raw, dtype=float))
        free = eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, free, replace=False)
    params, static = eqx.partition(model, free)
    theta, unravel = ravel_pytree(params)
    as_model = lambda th: eqx.combine(unravel(th), static)  # noqa: E731
    z = jnp.asarray(sp.states[:, 0])
    refit = eqx.filter_jit(gauss_newton)
    for _ in range(4):
        z = refit(model, z)
    # Jacobi preconditioner: diag(JᵀJ) ≈ E[(Jᵀv)²] over Rademacher v
    _, vjp = jax.vjp(lambda th: resid(as_model(th), z).ravel(), theta)
    vjp = jax.jit(vjp)
    diag = sum(
        vjp(jax.random.rademacher(jax.random.PRNGKey(i), (obs.size,), dtype=float))[0] ** 2 for i in range(16)
    )
    scale = jnp.sqrt(diag / 16)
    scale = jnp.maximum(scale, 1e-3 * jnp.median(scale[scale > 0]))

    @jax.jit
    def objective(x, z):
        m = as_model(x / scale)
        fitted = jax.lax.stop_gradient(gauss_newton(m, gauss_newton(m, z)))
        return jnp.sum(resid(m, fitted) ** 2) / n

    opt = optax.lbfgs(memory_size=20)

    @jax.jit
    def step(x, state, z):
        f = lambda xx: objective(xx, z)  # noqa: E731
        value, grad = optax.value_and_grad_from_state(f)(x, state=state)
        update, state = opt.update(grad, state, x, value=value, grad=grad, value_fn=f)
        x = optax.apply_updates(x, update)
        return x, state, gauss_newton(as_model(x / scale), z), value

    x = theta * scale
    state = opt.init(x)
    for k in range(iterations):
        x, state, z, value = step(x, state, z)
        if k == 0 or (k + 1) % max(1, iterations // 5) == 0:
            print(f"    iteration {k + 1}: mean square per axis on whole tracks {float(value):.6g} m²")
    return as_model(x / scale)


def levenberg_marquardt(model, learned, imported, iterations: int):
    """``model`` (the learned run's with the true flow in its place) after ``iterations`` of the
    library's whole-track Levenberg–Marquardt on the training tracks, moving the coefficient
    parameters ``fhnn train``'s phase moves in the ``learned`` model (the FHNN's
    :meth:`~fhnn.models.fhnn.FHNN.track_parameters`: its output layer and ``c_l``), the flow held."""
    held = jax.tree.map(lambda _: False, model.eom.flow)
    free = eqx.tree_at(lambda m: m.eom.flow, learned.track_parameters(), replace=held)
    fit = TrackFit(model, free, imported.train)
    for k in range(iterations):
        step = fit.step()
        c_l = float(step.model.coefficients(jnp.asarray(1.0), jnp.asarray(0.1))[3])
        if k == 0 or (k + 1) % max(1, iterations // 5) == 0 or not step.accepted:
            print(
                f"    iteration {k + 1}: mean square per axis on whole tracks {step.mean_square:.6g} m², "
                f"c_l {c_l:.5f}"
            )
        if not step.accepted:
            break
    return fit.model


def regressed_truth(model, scored):
    """``model`` with the simulator's flow and its coefficient net fitted to the true coefficient
    laws: raw outputs (before the caps) by least squares at the visited (r, σ) points, 4,000 Adam
    steps; ``c_l`` set to the true constant."""
    true_eom = scored.equations()
    coef = model.eom.coefficients
    points = jnp.asarray(visited_r_sigma(true_eom, scored))
    truth = np.asarray(jax.vmap(lambda p: jnp.stack(true_eom.coefficients(p[0], p[1])))(points))
    target = np.stack([uncap(truth[:, i], np.asarray(coef.caps[i]), coef.cap_map) for i in range(4)], 1)
    inputs = points / jnp.stack([coef.r_scale, coef.sigma_scale])
    opt = optax.adam(optax.cosine_decay_schedule(3e-3, 4000))

    @eqx.filter_jit
    def step(mlp, state):
        loss = lambda m: jnp.mean((jax.vmap(m)(inputs)[:, :3] - target[:, :3]) ** 2)  # noqa: E731
        grad = eqx.filter_grad(loss)(mlp)
        update, state = opt.update(grad, state, eqx.filter(mlp, eqx.is_array))
        return eqx.apply_updates(mlp, update), state

    mlp = coef.mlp
    state = opt.init(eqx.filter(mlp, eqx.is_array))
    for _ in range(4000):
        mlp, state = step(mlp, state)
    model = eqx.tree_at(lambda m: m.eom.flow, model, true_eom.flow)
    model = eqx.tree_at(lambda m: m.eom.coefficients.mlp, model, mlp)
    return eqx.tree_at(lambda m: m.eom.coefficients.c_l_raw, model, jnp.asarray(target[0, 3]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument(
        "runs",
        nargs="+",
        help="adam:W:B:STEPS:DRIFT, lbfgs:ITERATIONS:PARTS:W:DRIFT, tracks:ITERATIONS[:C_L] or "
        "known-flow:ITERATIONS:run|truth[:C_L] or known-flow-lm:ITERATIONS:run|truth",
    )
    args = p.parse_args()
    for spec in args.runs:  # checked before anything runs
        kind, *rest = spec.split(":")
        if kind == "known-flow-lm" and len(rest) == 2 and rest[0].isdigit() and rest[1] in ("run", "truth"):
            continue
        if kind == "known-flow" and len(rest) in (2, 3) and rest[1] in ("run", "truth"):
            rest = rest[:1] + rest[2:]
            kind = "tracks"
        if kind == "tracks" and len(rest) in (1, 2) and rest[0].isdigit():
            try:
                if len(rest) == 1 or float(rest[1]) > 0:
                    continue
            except ValueError:
                pass
        numbers = rest[:3] if kind == "adam" else rest[:1] + rest[2:3]
        ok = len(rest) == 4 and (kind == "adam" or (kind == "lbfgs" and rest[1] in ("all", "coef")))
        if not ok or rest[-1] not in ("free", "model") or not all(x.isdigit() for x in numbers):
            raise SystemExit(
                f"bad run {spec!r}: give adam:W:B:STEPS:free|model, "
                "lbfgs:ITERATIONS:all|coef:W:free|model, tracks:ITERATIONS[:C_L] or "
                "known-flow[-lm]:ITERATIONS:run|truth[:C_L]"
            )
    imported, scored, run = trained_run(args.out, args.data_seed)
    base = run.trainer(imported)
    train = base.batch(base.train_pairs)
    start = run.state.best_model
    print(f"data seed {args.data_seed}, the defaults' run: {score(start, base, train, scored)}")
    for spec in args.runs:
        kind, *rest = spec.split(":")
        began = time.perf_counter()
        print(f"{spec}:")
        if kind == "adam":
            w, b, n = (int(x) for x in rest[:3])
            model = adam(start, imported, base, w, b, n, rest[3], args.lr)
        elif kind == "lbfgs":
            model = lbfgs(start, imported, base, int(rest[0]), rest[1], int(rest[2]), rest[3])
        elif kind == "tracks":
            model = tracks(start, imported, int(rest[0]), float(rest[1]) if len(rest) > 1 else None)
        else:
            begin = scored_models(start, scored.equations())["true flow, learned coefficients"]
            if rest[1] == "truth":
                begin = regressed_truth(start, scored)
            print(f"  start: {score(begin, base, train, scored)}")
            if kind == "known-flow-lm":
                model = levenberg_marquardt(begin, start, imported, int(rest[0]))
            else:
                c_l = float(rest[2]) if len(rest) > 2 else None
                model = tracks(begin, imported, int(rest[0]), c_l, parts="coef")
        print(f"  after ({time.perf_counter() - began:.0f} s): {score(model, base, train, scored)}")
        if kind in ("tracks", "known-flow", "known-flow-lm"):
            mixes = scored_models(model, scored.equations())
            misfits = {
                "before": start if kind == "tracks" else begin,
                "after": model,
                "its flow, true coefficients": mixes["learned flow, true coefficients"],
                "truth": mixes["truth"],
            }
            print(
                "  whole-track misfit per axis (training tracks, start states fitted): "
                + "; ".join(f"{k} {track_misfit(m, imported.train):.6g} m²" for k, m in misfits.items())
            )


if __name__ == "__main__":
    main()
