"""How long an interval between two samples training may step over: the position error of one
RK4 step (what the multi-step loss takes per sample interval) against the interval's length, on
the states of issue 14's tracks (``benchmarks/own_data.py``'s simulation: ``steady_vortex`` with
actuation, observed about every 0.05 s), under the simulator's own equations without forcing.
It sets :data:`fhnn.data.cleaning.GAP_STEPS`, the multiple of a track's median step beyond which
``fhnn import`` splits the track (``--max-gap auto``).

Usage::

    python benchmarks/gap_steps.py [--out DIR] [--states N]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from own_data import OBSERVED, make_data

from fhnn.data.cleaning import GAP_STEPS
from fhnn.physics.integrators import rk4_step

#: RK4 steps of the reference over one interval.
REFERENCE_STEPS = 2000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    parser.add_argument("--states", type=int, default=400)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    fine = make_data(args.out, 0)[0]
    eom = fine.equations()
    states = fine.train.states_clean[:, ::50].reshape(-1, 4)
    states = jnp.asarray(states[np.random.default_rng(0).choice(len(states), args.states, replace=False)])

    def f(x: jax.Array, t: jax.Array) -> jax.Array:
        return eom(x, t, jnp.zeros(2))

    def reference(x: jax.Array, h: float) -> jax.Array:
        return jax.lax.scan(
            lambda y, _: (rk4_step(f, y, 0.0, h / REFERENCE_STEPS), None), x, None, REFERENCE_STEPS
        )[0]

    step = OBSERVED["step"]
    noise = 1e-3
    print(
        f"one RK4 step over an interval of k median steps ({step} s), position error against "
        f"{REFERENCE_STEPS} RK4 steps, {args.states} states of issue 14's training tracks "
        f"(noise of the positions: {noise:g} m)"
    )
    for k in (1, 2, 5, 10, 20, 40, 100):
        h = k * step
        one = jax.vmap(lambda x, h=h: rk4_step(f, x, 0.0, h))(states)
        ref = jax.vmap(lambda x, h=h: reference(x, h))(states)
        err = np.linalg.norm(np.asarray(one - ref)[:, :2], axis=1)
        mark = "  <- GAP_STEPS (--max-gap auto)" if k == GAP_STEPS else ""
        print(
            f"  k = {k:3d} ({h:5.2f} s): median {np.median(err):.1e} m, 95th percentile "
            f"{np.percentile(err, 95):.1e} m, max {err.max():.1e} m{mark}"
        )


if __name__ == "__main__":
    main()
