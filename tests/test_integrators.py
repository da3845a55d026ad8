"""Integrators: RK4 has order 4; the adaptive solver meets exact solutions."""

import jax.numpy as jnp
import numpy as np

from fhnn.physics.integrators import adaptive_solve, rk4_solve


def oscillator(s, t):
    # x'' = -x - 0.1 x' + cos(t): forced, damped; exact solution computed below
    return jnp.stack([s[1], -s[0] - 0.1 * s[1] + jnp.cos(t)])


def exact(t):
    # particular solution of x'' + 0.1x' + x = cos t is x_p = 10 sin t; with x(0)=0, x'(0)=10
    # the homogeneous part vanishes.
    return np.stack([10 * np.sin(t), 10 * np.cos(t)], axis=-1)


def test_rk4_convergence_order_is_four():
    errors, steps = [], []
    for n in (20, 40, 80, 160, 320):
        ts = jnp.linspace(0.0, 10.0, n + 1)
        ys = rk4_solve(oscillator, jnp.asarray([0.0, 10.0]), ts)
        errors.append(np.abs(np.asarray(ys[-1]) - exact(10.0)).max())
        steps.append(10.0 / n)
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - 4.0) < 0.15, slope


def test_adaptive_solver_meets_exact_solution():
    ts = jnp.linspace(0.0, 30.0, 301)
    truth = exact(np.asarray(ts))  # amplitude 10
    ys, ok = adaptive_solve(oscillator, jnp.asarray([0.0, 10.0]), ts, rtol=1e-12, atol=1e-12)
    assert bool(ok)
    # dense output between steps: measured 2.1e-9 (relative 2e-10)
    assert np.abs(np.asarray(ys) - truth).max() < 5e-9
    # steps clipped onto the outputs: step-end accuracy
    ys, ok = adaptive_solve(oscillator, jnp.asarray([0.0, 10.0]), ts, rtol=1e-12, atol=1e-12, dense=False)
    assert bool(ok)
    assert np.abs(np.asarray(ys) - truth).max() < 5e-11


def test_adaptive_solver_reports_failure():
    blow_up = lambda s, t: s**2  # noqa: E731  (s' = s², s(0) = 1 blows up at t = 1)
    ys, ok = adaptive_solve(blow_up, jnp.asarray([1.0]), jnp.linspace(0.0, 2.0, 5), max_steps=1000)
    assert not bool(ok)
    assert not np.all(np.isfinite(np.asarray(ys)))
