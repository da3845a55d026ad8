"""Where an L-BFGS polish iteration's time goes: the iteration against its objective.

The default plan's polish (``fhnn.training.quasi_newton.quasi_newton_step``: optax's L-BFGS with a
zoom line search, on the parameters raveled into one vector) is most of a default-plan run. This
times one iteration, as the trainer runs it, against one evaluation of its objective and gradient
on the same pairs, and against the same iteration on the model's parameter tree (optax on each
leaf, as the trainer ran it before; ``tree_step`` below), for the default plan's FHNN on
``solid_body_vortex`` at a few pair-set sizes and memory sizes. A ratio of iteration to objective
well above 1 says the iteration's cost is the optimiser's own work (the two-loop recursion over
``memory`` pairs, the line search's extra evaluations and, on a GPU, its loop's host round trips),
not the model's. Each configuration is timed from the same starting model after 20 warm
iterations, so the line search's number of evaluations can differ between configurations. The
iteration is timed three ways on the vector, in turn: the plain jitted function; its stored program
(:class:`fhnn.executables.StoredProgram`), as the trainer ran it before; and the stored program with
the vector and the optimiser's state donated to its outputs, as the trainer runs it now, so the
memory of ``memory`` pairs (~7 MB at 100) is updated in place instead of copied every iteration.

Usage::

    python benchmarks/lbfgs_overhead.py [--iterations 200] [--out DIR]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from _common import dataset, seconds_per_call
from jax.flatten_util import ravel_pytree

import fhnn
from fhnn.executables import StoredProgram
from fhnn.models.registry import MODELS
from fhnn.runtime import use_compilation_cache
from fhnn.training.plans import DEFAULT_PLAN, PLANS
from fhnn.training.run import RunConfig
from fhnn.training.trainer import (
    QUASI_NEWTON_FIELDS,
    Trainer,
    quasi_newton_objective,
    quasi_newton_step,
    strong_types,
)

#: (pairs, memory) configurations timed; the default plan's is (4,000, 100), the reproduction's
#: (2,000, 100).
CONFIGS = ((4000, 100), (2000, 100), (2000, 30), (2000, 10))
#: Timings of each vector variant per configuration, taken in turn (the median is printed).
ROUNDS = 3


@eqx.filter_jit
def tree_step(params, opt_state, static, data, scales, config):
    """:func:`quasi_newton_step` on the parameter tree itself (optax's operations once per leaf)."""
    opt = optax.lbfgs(memory_size=config.lbfgs_memory)

    def objective(p):
        return quasi_newton_objective(p, static, data, scales, config)

    value, grad = optax.value_and_grad_from_state(objective)(params, state=opt_state)
    updates, opt_state = opt.update(grad, opt_state, params, value=value, grad=grad, value_fn=objective)
    return optax.apply_updates(params, updates), opt_state, value


def per_iteration(step, x, state, iterations: int) -> float:
    """Seconds per call of ``step(x, state) -> (x, state, value)``, each call continuing from the
    last, after 20 calls (the first compiles) and the warm call of :func:`seconds_per_call`."""
    for _ in range(20):
        x, state, _ = step(x, state)
    carry = [x, state]

    def call():
        carry[0], carry[1], value = step(*carry)
        return value

    return seconds_per_call(call, iterations)


def time_iteration(ds, run: RunConfig, model, pairs: int, memory: int, iterations: int) -> dict:
    """Seconds per L-BFGS iteration on one vector — plain jitted, stored as the trainer ran it
    before, and stored with the vector and state donated as the trainer runs it now: the median of
    :data:`ROUNDS` timings taken in turn, so a slow spell of the machine falls on all three — on the
    parameter tree, and per objective-and-gradient evaluation."""
    cfg = run.train.replace(lbfgs_pairs=pairs, lbfgs_memory=memory)
    trainer = Trainer(cfg, ds.train, ds.val)
    batch = {**trainer.quasi_newton_windows().as_jax(), "key": jax.random.PRNGKey(4)}
    params, static = eqx.partition(model, eqx.is_array)
    qn, scales = cfg.only(QUASI_NEWTON_FIELDS), trainer.scales
    flat = ravel_pytree(params)[0]
    opt = optax.lbfgs(memory_size=memory)
    own = lambda t: jax.tree.map(lambda x: jnp.array(x, copy=True), t)  # noqa: E731 (no shared buffers)
    steps = {
        "plain": quasi_newton_step,
        "stored": StoredProgram(quasi_newton_step),
        "donated": StoredProgram(quasi_newton_step, donate=(0, 1)),
    }
    times: dict[str, list[float]] = {name: [] for name in steps}
    for _ in range(ROUNDS):
        for name, step in steps.items():
            times[name].append(
                per_iteration(
                    lambda f, s, step=step: step(f, s, params, static, batch, scales, qn),
                    own(flat),
                    own(strong_types(opt.init(flat))),
                    iterations,
                )
            )
    out = {name: float(np.median(t)) for name, t in times.items()}
    out["tree"] = per_iteration(
        lambda p, s: tree_step(p, s, static, batch, scales, qn),
        params,
        strong_types(opt.init(params)),
        iterations,
    )
    objective = lambda p: quasi_newton_objective(p, static, batch, scales, qn)  # noqa: E731
    value_and_grad = jax.jit(jax.value_and_grad(objective))
    out["objective"] = seconds_per_call(lambda: value_and_grad(params), 50)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--iterations", type=int, default=200)
    p.add_argument("--out", type=Path, default=Path("benchmarks/_lbfgs_overhead"))
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    use_compilation_cache(tempfile.mkdtemp(prefix="fhnn-lbfgs-"))  # the store needs a folder
    platform = jax.devices()[0].platform
    print(f"fhnn {fhnn.__version__}, jax {jax.__version__}, {platform}, {os.cpu_count()} CPUs")
    ds, _ = dataset("solid_body_vortex", args.out)
    run = RunConfig().with_settings(PLANS[DEFAULT_PLAN].settings("fhnn"))
    model = MODELS["fhnn"].make(run.model, MODELS["fhnn"].arguments(ds), 0)
    print("solid_body_vortex, the default plan's FHNN; one L-BFGS iteration against one objective+gradient")
    for pairs, memory in CONFIGS:
        t = {k: v * 1e3 for k, v in time_iteration(ds, run, model, pairs, memory, args.iterations).items()}
        print(
            f"  {pairs:5d} pairs, memory {memory:3d}: iteration {t['plain']:5.2f} ms plain, "
            f"{t['stored']:5.2f} stored, {t['donated']:5.2f} stored with its state donated "
            f"({t['stored'] / t['donated']:.2f}x faster); objective+gradient {t['objective']:5.2f} ms "
            f"(ratio {t['donated'] / t['objective']:.1f}); on the parameter tree {t['tree']:5.2f} ms"
        )


if __name__ == "__main__":
    main()
