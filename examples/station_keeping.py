"""Worked example: hold a turning body on station inside the vortex with a learned 3-DOF model.

    python examples/station_keeping.py --run RUN [--data FILE.h5] [--seconds 30] [--json]
    python examples/station_keeping.py --fast

Model-predictive control: every 0.5 s the controller chooses the thrusters' next 3 s (six held
values of surge force, sway force and yaw moment, each bounded by a tanh) that keep the body's
predicted position near the station (3, 0) m, where the current runs at 0.27 m/s, at least
thrust, the heading free, by 40 L-BFGS
iterations through RK4 forecasts of the model; it applies the first value to the true body for
0.5 s, and starts again from the shifted plan. The forecasts are offset-free: each planned
interval adds the last interval's prediction error (the body's state less the model's forecast of
it), so a model's steady bias is corrected from what the body did rather than left as an offset.
The same controller runs once with the learned model
(``--run``, the folder ``fhnn turning train`` wrote) and once with the true equations; the RMS
distance from the station over the last two thirds of the run, and their ratio, are printed (issue
71's target: the learned model's at most 1.2 × the true one's). Drift without control is printed
beside them.

``--fast`` runs the true model only, over 6 s with 15 iterations per step (the tests run it so).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from fhnn.physics.integrators import rk4_step
from fhnn.physics.planar_scenarios import get_planar_scenario

STATION = jnp.array([3.0, 0.0])  # [m], where the vortex's current is 0.27 m/s along +y
START = jnp.array([3.0, 0.0, -0.5 * np.pi, 0.0, 0.0, 0.0])  # on station, at rest, bow into the current
LIMITS = jnp.array([2.0, 2.0, 0.5])  # |X|, |Y| [N], |N| [N·m]
INTERVAL = 0.5  # [s] between decisions, each thrust held for one
HORIZON = 6  # intervals planned
SUBSTEPS = 5  # RK4 steps per interval in the plan
WEIGHTS = {"position": 1.0, "thrust": 1e-3}


def held(field, state, t, tau, steps: int = SUBSTEPS):
    """The state after one interval under thrust ``tau`` held, by ``steps`` RK4 steps."""
    h = INTERVAL / steps

    def body(i, s):
        return rk4_step(lambda x, tt: field(x, tt, tau), s, t + i * h, h)

    return jax.lax.fori_loop(0, steps, body, state)


def plan_cost(raw, field, state, t, offset):
    """Predicted cost of the plan ``raw`` (HORIZON, 3), unbounded, from ``state`` at ``t``, each
    interval's forecast corrected by ``offset`` (6,), the last interval's prediction error."""
    taus = LIMITS * jnp.tanh(raw)

    def step(carry, tau):
        s, tt = carry
        s = held(field, s, tt, tau) + offset
        cost = WEIGHTS["position"] * jnp.sum((s[:2] - STATION) ** 2) + WEIGHTS["thrust"] * jnp.sum(
            (tau / LIMITS) ** 2
        )
        return (s, tt + INTERVAL), cost

    _, costs = jax.lax.scan(step, (state, t), taus)
    return jnp.sum(costs)


def controller(field, iterations: int):
    """A compiled ``(raw plan, state, t, offset) -> better raw plan`` by L-BFGS on
    :func:`plan_cost`."""
    opt = optax.lbfgs()

    @eqx.filter_jit
    def improve(raw, state, t, offset):
        def f(r):
            return plan_cost(r, field, state, t, offset)

        value_and_grad = optax.value_and_grad_from_state(f)

        def body(_, carry):
            r, s = carry
            value, grad = value_and_grad(r, state=s)
            updates, s = opt.update(grad, s, r, value=value, grad=grad, value_fn=f)
            return optax.apply_updates(r, updates), s

        raw, _ = jax.lax.fori_loop(0, iterations, body, (raw, opt.init(raw)))
        return raw

    return improve


def closed_loop(model, plant, seconds: float, iterations: int, control: bool = True) -> np.ndarray:
    """Positions and headings ``(steps + 1, 3)`` of the true ``plant`` under MPC with ``model``
    (or drifting without thrust when ``control`` is false), one row per interval."""
    improve = controller(model, iterations)
    true_step = eqx.filter_jit(lambda s, t, tau: held(plant, s, t, tau, steps=20))
    model_step = eqx.filter_jit(lambda s, t, tau: held(model, s, t, tau))
    raw = jnp.zeros((HORIZON, 3))
    state, t, offset = START, 0.0, jnp.zeros(6)
    poses = [np.asarray(state[:3])]
    for _ in range(round(seconds / INTERVAL)):
        tau = jnp.zeros(3)
        if control:
            raw = improve(raw, state, jnp.asarray(t), offset)
            tau = LIMITS * jnp.tanh(raw[0])
            raw = jnp.concatenate([raw[1:], raw[-1:]])  # warm start: the plan shifted
            predicted = model_step(state, jnp.asarray(t), tau)
        state = true_step(state, jnp.asarray(t), tau)
        if control:
            offset = state - predicted
        t += INTERVAL
        poses.append(np.asarray(state[:3]))
    return np.array(poses)


def rms_distance(poses: np.ndarray) -> float:
    """RMS distance [m] from the station over the last two thirds of the run."""
    tail = poses[len(poses) // 3 :, :2]
    return float(np.sqrt(np.mean(np.sum((tail - np.asarray(STATION)) ** 2, axis=1))))


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--run", type=Path, help="run folder of `fhnn turning train`")
    p.add_argument("--scenario", default="turning_vortex", help="the true body and flow")
    p.add_argument("--seconds", type=float, default=30.0)
    p.add_argument("--iterations", type=int, default=40)
    p.add_argument("--fast", action="store_true", help="true model only, 6 s, 15 iterations")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    args = p.parse_args(argv)
    if args.run is None and not args.fast:
        p.error("give --run RUN (a folder of `fhnn turning train`) or --fast")
    seconds, iterations = (6.0, 15) if args.fast else (args.seconds, args.iterations)
    plant = get_planar_scenario(args.scenario).equations()
    start = time.perf_counter()
    result = {"seconds": seconds, "iterations": iterations, "scenario": args.scenario}
    result["drift"] = rms_distance(closed_loop(plant, plant, seconds, iterations, control=False))
    result["true_model"] = rms_distance(closed_loop(plant, plant, seconds, iterations))
    if args.run is not None:
        from fhnn.api.planar import load_turning

        learned = load_turning(args.run)
        result["learned_model"] = rms_distance(closed_loop(learned, plant, seconds, iterations))
        result["ratio"] = result["learned_model"] / result["true_model"]
    result["wall_seconds"] = time.perf_counter() - start
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"RMS distance from the station over the last {2 * seconds / 3:g} s: drifting "
            f"{result['drift']:.3g} m, MPC with the true model {result['true_model']:.3g} m"
            + (
                f", with the learned model {result['learned_model']:.3g} m (ratio {result['ratio']:.3f})"
                if "ratio" in result
                else ""
            )
        )
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
