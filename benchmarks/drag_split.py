"""How sharply the data tell ``c_l`` from ``c_q(σ)``: the loss profiled over a pinned ``c_l``.

A trained FHNN run (by default the ``steady_vortex`` run ``benchmarks/fhnn_targets.py`` keeps) is
polished again, from its own best model, with ``c_l`` held at each of several values and every other
parameter free (the run's own quasi-Newton phase: L-BFGS on its seeded training pairs, the same loss).
For each value the script prints the training loss reached, the validation loss, and the recovery of
``c_l`` and of ``c_q`` per σ band against the simulator's truth. The loss's profile over ``c_l`` is what
the data say about the split of the drag: where it is flat to within the differences the fit itself
leaves (the free polish's), the data cannot place ``c_l`` more finely than that, and a ``c_l`` off by δ is
made up by a ``c_q`` off by δ / (½ρAσ), largest at small σ (issue 13's open c_q bands).

The pinned value enters the objective as an argument (one compiled program for every value); its
coordinate of the parameter vector then has zero gradient, so L-BFGS keeps it where it was set.

Usage::

    python benchmarks/drag_split.py [--run DIR] [--data FILE] [--iterations N]
        [--values 3.0,3.024,...]

``--values``: the c_l values [N·s/m] to pin; default the truth, the learned value and ±0.5 %, ±1 % of it.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.flatten_util import ravel_pytree

from fhnn.data.dataset import read_dataset
from fhnn.evaluation.recovery import coefficient_recovery, coefficients_at
from fhnn.training.run import Run
from fhnn.training.trainer import quasi_newton_objective, strong_types

C_L_CAP = 10.0  # the capped map's C for c_l (fhnn.models.fhnn: C = (60, 60, 2, 10))


def c_l_of(model) -> float:
    """The model's (constant) linear drag coefficient [N·s/m]."""
    return float(coefficients_at(model.coefficients, jnp.asarray([[1.0, 0.1]]))[0, 3])


def raw_for(c_l: float) -> float:
    """The raw output z with ``C · tanh(softplus(z) / C) = c_l``."""
    s = C_L_CAP * np.arctanh(c_l / C_L_CAP)
    return float(s + np.log(-np.expm1(-s)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, default=Path("benchmarks/_fhnn_targets/run_steady_vortex"))
    p.add_argument("--data", type=Path, default=Path("benchmarks/_fhnn_targets/steady_vortex.h5"))
    p.add_argument("--iterations", type=int, default=3000)
    p.add_argument("--values", default=None, help="comma-separated c_l values [N·s/m]")
    args = p.parse_args()
    dataset = read_dataset(args.data)
    run = Run.load(args.run)
    learned = run.state.best_model
    if getattr(learned.coefficients, "c_l_raw", None) is None:
        raise SystemExit("the run's c_l is not one learned constant (model.linear_drag must be 'constant')")
    trainer = run.trainer(dataset)
    cfg = trainer.config
    batch = trainer.batch(trainer.quasi_newton_windows(), jax.random.PRNGKey(cfg.seed + 4))
    params, static = eqx.partition(learned, eqx.is_array)
    flat0, unravel = ravel_pytree(params)
    marker = ravel_pytree(
        eqx.tree_at(
            lambda m: m.eom.coefficients.c_l_raw,
            jax.tree.map(jnp.zeros_like, params),
            jnp.ones(()),
        )
    )[0]
    index = int(jnp.argmax(marker))
    assert float(marker.sum()) == 1.0
    opt = optax.lbfgs(memory_size=cfg.lbfgs_memory)
    scales = trainer.scales

    def objective(f, pin):
        return quasi_newton_objective(unravel(f.at[index].set(pin)), static, batch, scales, cfg)

    @jax.jit
    def step(f, state, pin):
        fn = lambda g: objective(g, pin)  # noqa: E731
        value, grad = optax.value_and_grad_from_state(fn)(f, state=state)
        updates, state = opt.update(grad, state, f, value=value, grad=grad, value_fn=fn)
        return optax.apply_updates(f, updates), state, value

    truth = float(dataset.equations().coefficients(jnp.asarray(1.0), jnp.asarray(0.1))[3])
    c_l0 = c_l_of(learned)
    values = (
        [float(v) for v in args.values.split(",")]
        if args.values
        else sorted({truth, c_l0, *(c_l0 * (1 + d) for d in (-0.01, -0.005, 0.005, 0.01))})
    )
    free_val = trainer.validate(learned)["total"]
    print(
        f"run {args.run} on {args.data}: learned c_l {c_l0:.5g} (truth {truth:.5g}, "
        f"{c_l0 / truth - 1:+.2%}); validation loss {free_val:.4e}; polish of {args.iterations} L-BFGS "
        f"iterations on {cfg.lbfgs_pairs} pairs from the learned model, c_l pinned"
    )
    header = f"{'c_l':>8} {'vs truth':>9} {'train loss':>11} {'val loss':>11} {'val/free':>9}"
    print(header + "  c_q max rel. error per σ band (share)")
    for value in values:
        t0 = time.perf_counter()
        pin = jnp.asarray(raw_for(value))
        f = jnp.array(flat0, copy=True).at[index].set(pin)
        state = strong_types(opt.init(f))
        for _ in range(args.iterations):
            f, state, loss = step(f, state, pin)
        model = eqx.combine(unravel(f.at[index].set(pin)), static)
        val = trainer.validate(model)["total"]
        rec = coefficient_recovery(model.coefficients, dataset)
        bands = ", ".join(f"{b['c_q']:.2%} ({b['quadratic_share']:.0%})" for b in rec["_by_sigma"])
        print(
            f"{c_l_of(model):8.5g} {c_l_of(model) / truth - 1:+9.2%} {float(loss):11.4e} {val:11.4e} "
            f"{val / free_val:9.3f}  {bands}  [{time.perf_counter() - t0:.0f} s]"
        )


if __name__ == "__main__":
    main()
