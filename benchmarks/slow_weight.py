"""Where an unweighted fit leaves the drag wrong, and what weighting the slow windows does.

Two measurements behind ``model.slow_weight`` (``docs/design/data/slow_weight.txt``):

- ``curve``: a trained FHNN run's ``c_q(σ)`` and total drag coefficient ``K = ½ρA c_q σ + c_l``
  against the simulator's truth on a grid of σ at two radii (``steady_vortex``'s law): where the
  fit is exact, where it is not;
- ``polish``: that run's best model polished again (L-BFGS, ``--iterations``, ``--pairs`` random
  training pairs, derivative and one-step loss) with each pair weighted by ``min((σ̃/σ)^p, 50)``
  (``--power p``; σ under the model at the polish's start, held fixed; σ̃ the median), or unweighted
  with ``--power 0`` — printing every 500 iterations the unweighted validation loss on as many
  validation pairs, ``c_l``'s and the masses' errors and ``c_q``'s per σ band; ``--part
  coefficients`` moves the coefficient net alone, the flow held where it is.

Usage::

    python benchmarks/slow_weight.py curve RUN DATA
    python benchmarks/slow_weight.py polish RUN DATA [--power 2] [--iterations 3000] [--pairs 8000]
        [--part all|coefficients]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree

from fhnn.data.dataset import read_dataset
from fhnn.data.windows import LossScales, Windows
from fhnn.evaluation.recovery import coefficient_recovery
from fhnn.training.run import Run


def curve(model) -> None:
    co = model.coefficients
    sig = np.array([0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.12, 0.2, 0.3, 0.5, 0.8])
    true = 0.6 + 0.4 / (1 + sig / 0.2)  # steady_vortex's c_q law (docs/spec.md §1)
    for r in (1.0, 2.5):
        out = np.asarray(jax.vmap(lambda s, r=r: co(jnp.asarray(r), s))(jnp.asarray(sig)))
        print(f"r {r} c_l {out[0, 3]}")
        print(" sigma  c_q  true  rel   drag_rel")
        for s, c, t, cl in zip(sig, out[:, 2], true, out[:, 3], strict=True):
            k, kt = 10 * c * s + cl, 10 * t * s + 3  # ½ρA = 10 kg/m, c_l = 3 N·s/m
            print(f" {s:.3f} {c:.4f} {t:.4f} {c / t - 1:+.3%} {k / kt - 1:+.3%}")


def polish(model, ds, power: float, iterations: int, pairs: int, part: str = "all") -> None:
    model = dataclasses.replace(model, slow_weight=0.0)  # the weights below, held fixed, and no others
    rng = np.random.default_rng(0)
    tw, vw = Windows.of(ds.train, 2), Windows.of(ds.val, 2)
    tw = tw.subset(np.sort(rng.choice(len(tw), pairs, replace=False)))
    vw = vw.subset(np.sort(rng.choice(len(vw), pairs, replace=False)))
    sc = LossScales.of(Windows.of(ds.train, 2))
    scales = (jnp.asarray(sc.deriv), jnp.asarray(sc.step))
    tb, vb = tw.as_jax(), vw.as_jax()

    def loss(m, b):  # derivative + one-step loss; weighted where b holds "weight"
        t = m.loss_terms(b, scales)
        return t["deriv"] + t["step"]

    weighted = dataclasses.replace(model, slow_weight=power)  # the library's weights under it
    w = weighted.quasi_newton_weights(tb) if power > 0 else jnp.ones(len(tw))
    share = float(jnp.sort(w)[-pairs // 100 :].sum() / w.sum())
    print(f"weights: max {float(w.max())}, share of the 1 % slowest pairs {share}")
    if part == "coefficients":  # the coefficient net alone; the flow held where it is
        spec = jax.tree.map(lambda _: False, model)
        spec = eqx.tree_at(
            lambda m: m.eom.coefficients, spec, jax.tree.map(eqx.is_inexact_array, model.eom.coefficients)
        )
        params, static = eqx.partition(model, spec)
    else:
        params, static = eqx.partition(model, eqx.is_inexact_array)
    flat, unravel = ravel_pytree(params)
    objective = lambda f: loss(eqx.combine(unravel(f), static), {**tb, "weight": w})  # noqa: E731
    opt = optax.lbfgs(memory_size=100)

    @jax.jit
    def step(f, state):
        v, g = optax.value_and_grad_from_state(objective)(f, state=state)
        u, state = opt.update(g, state, f, value=v, grad=g, value_fn=objective)
        return optax.apply_updates(f, u), state

    val = jax.jit(lambda f: loss(eqx.combine(unravel(f), static), vb))
    state, t0 = opt.init(flat), time.perf_counter()

    def report(f, i):
        c = coefficient_recovery(eqx.combine(unravel(f), static).coefficients, ds)
        bands = ", ".join(f"{b['c_q']:.2%}({b['quadratic_share']:.0%})" for b in c["_by_sigma"])
        print(
            f"it {i:5d} {time.perf_counter() - t0:5.0f}s val {float(val(f)):.3e} "
            f"c_l {c['c_l']['max_rel']:.3%} m_ax {c['m_ax']['max_rel']:.2%} bands {bands}",
            flush=True,
        )

    report(flat, 0)
    for i in range(1, iterations + 1):
        flat, state = step(flat, state)
        if i % 500 == 0:
            report(flat, i)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=["curve", "polish"])
    p.add_argument("run")
    p.add_argument("data")
    p.add_argument("--power", type=float, default=2.0)
    p.add_argument("--iterations", type=int, default=3000)
    p.add_argument("--pairs", type=int, default=8000)
    p.add_argument("--part", choices=["all", "coefficients"], default="all", help="what the polish moves")
    args = p.parse_args()
    model = Run.load(args.run).state.best_model
    if args.what == "curve":
        curve(model)
    else:
        polish(model, read_dataset(args.data), args.power, args.iterations, args.pairs, args.part)


if __name__ == "__main__":
    main()
