"""How well can the FHNN's stream net represent a scenario's flow at all? A diagnosis for the flow
recovery targets, not a training plan.

The stream net (the default plan's width, its linear far field and, for a time-dependent flow, its
harmonic basis in time) is fitted by L-BFGS directly to the simulator's true velocity at the
training split's clean samples — supervised, with the flow known; a reference, not a strict
bound, since the fit stops after ``--iterations`` — and then scored as ``fhnn inspect`` and the
reproduction's T6 score a learned flow: relative L2 error on the grid over the region the data
cover, pooled over the data's time window (:func:`fhnn.evaluation.recovery.flow_recovery`). The
gap between the error at the samples and the error on the grid is the part the samples leave
loose (near an obstacle few trajectories pass; a time-dependent flow is seen only where a body is
at each time). Results: ``docs/benchmarks/flow_ceiling.txt``.

Usage::

    python benchmarks/flow_ceiling.py [--scenario NAME ...] [--data-seed 0] [--iterations 2000] [--width W]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from _common import dataset

from fhnn.evaluation.recovery import flow_recovery
from fhnn.models.registry import MODELS
from fhnn.training.run import RunConfig

SCENARIOS = ("steady_vortex", "time_varying_vortex", "noisy_flow", "obstacle", "wave")


def ceiling(ds, iterations: int, width: int | None = None, points: int = 8000) -> dict:
    """Fit the stream net of a fresh default-plan FHNN (of ``width`` when given) to the true flow
    at ``points`` training samples; the width fitted, the relative L2 error there and on the
    recovery grid."""
    settings = {}  # the default plan's model: the configuration defaults
    if width is not None:
        settings["model.width"] = width
    model_config = RunConfig().with_settings(settings).model
    model = MODELS["fhnn"].make(model_config, MODELS["fhnn"].arguments(ds), 0)
    true = ds.equations().flow
    split = ds.train
    states = split.states_clean[split.mask]  # (samples, 4)
    times = np.broadcast_to(split.t, split.mask.shape)[split.mask]
    pick = np.random.default_rng(0).choice(len(states), min(points, len(states)), replace=False)
    xy, t = jnp.asarray(states[pick, :2]), jnp.asarray(times[pick])
    target = jax.vmap(true.velocity)(xy, t)
    norm = jnp.mean(jnp.sum(target**2, axis=-1))
    params, static = eqx.partition(model.flow, eqx.is_array)

    def loss(p):
        u = jax.vmap(eqx.combine(p, static).velocity)(xy, t)
        return jnp.mean(jnp.sum((u - target) ** 2, axis=-1)) / norm

    opt = optax.lbfgs(memory_size=100)
    value_and_grad = optax.value_and_grad_from_state(loss)

    @jax.jit
    def step(p, state):
        value, grad = value_and_grad(p, state=state)
        updates, state = opt.update(grad, state, p, value=value, grad=grad, value_fn=loss)
        return optax.apply_updates(p, updates), state

    state = opt.init(params)
    t0 = time.perf_counter()
    for _ in range(iterations):
        params, state = step(params, state)
    fitted = eqx.combine(params, static)
    return {
        "width": model_config.width,
        "samples_rel_l2": float(np.sqrt(loss(params))),
        "grid_rel_l2": flow_recovery(fitted, ds)["rel_l2"],
        "seconds": round(time.perf_counter() - t0, 1),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", action="append", choices=SCENARIOS, default=None)
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--iterations", type=int, default=2000)
    p.add_argument("--width", type=int, default=None, help="stream net width [default: the plan's]")
    p.add_argument("--out", type=Path, default=Path("benchmarks/_flow_ceiling"))
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.scenario or SCENARIOS:
        result = ceiling(dataset(name, args.out, args.data_seed)[0], args.iterations, args.width)
        head = {"scenario": name, "data_seed": args.data_seed, "iterations": args.iterations}
        print(json.dumps({**head, **result}))


if __name__ == "__main__":
    main()
