"""Integrators: RK4 has order 4; the adaptive solver meets exact solutions."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from fhnn.physics.integrators import (
    STALL_PATIENCE,
    StallGuard,
    adaptive_solve,
    rk4_solve,
    rk4_step,
    solve_forced_batch,
)


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


def test_rk4_step_with_a_given_first_stage_is_the_same_step():
    # the training loss hands f(s, t) to the step; a wrong k1 must change the step (it is used)
    s, t, dt = jnp.asarray([0.3, -1.2]), jnp.asarray(0.7), jnp.asarray(0.05)
    plain = np.asarray(rk4_step(oscillator, s, t, dt))
    given = np.asarray(rk4_step(oscillator, s, t, dt, k1=oscillator(s, t)))
    np.testing.assert_array_equal(given, plain)
    wrong = np.asarray(rk4_step(oscillator, s, t, dt, k1=oscillator(s, t) + 1.0))
    assert np.abs(wrong - plain).min() > 1e-3


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


def test_output_times_out_of_order_fail_the_solve_instead_of_raising():
    # fhnn.runtime sets EQX_ON_ERROR=nan: Diffrax's check of the output times gives NaN times,
    # and the solve reports the failure through ok like any other
    times = jnp.asarray([0.0, 2.0, 1.0, 3.0])
    for dense in (True, False):
        ys, ok = adaptive_solve(oscillator, jnp.asarray([0.0, 10.0]), times, dense=dense)
        assert not bool(ok) and not np.any(np.isfinite(np.asarray(ys)))


class ForcedSpring(eqx.Module):
    """``ẍ = −k x + F`` in the plane, in the field signature of the models and the true equations."""

    k: jax.Array

    def __call__(self, s, t, force):
        return jnp.stack([s[2], s[3], -self.k * s[0] + force[0], -self.k * s[1] + force[1]])


def test_rollouts_call_no_python_so_the_compilation_cache_keeps_them():
    """JAX neither caches nor exports a program that calls back into Python, as Equinox's runtime
    checks do by default (Diffrax checks the output times with them): every process compiled every
    rollout and simulation again. Under fhnn's setting the checks are computed in the program, and
    the rollout is the exact solution all the same."""
    ts = jnp.linspace(0.0, 2.0, 21)
    y0 = jnp.asarray([[1.0, 0.5, 0.0, 0.0], [0.0, 0.0, 0.3, -0.2]])
    actuation, residual = jnp.zeros((2, 2, 3, 3)), jnp.zeros((2, 21, 2))
    args = (
        ForcedSpring(jnp.asarray(4.0)),
        y0,
        actuation,
        ts,
        1e-12,
        1e-12,
        10_000,
        jnp.asarray(1e3),
        residual,
    )
    assert "callback" not in solve_forced_batch.lower(*args).as_text()
    ys, ok = solve_forced_batch(*args)
    t = np.asarray(ts)[:, None]
    x = np.asarray(y0[:, None, :2]) * np.cos(2 * t) + np.asarray(y0[:, None, 2:]) / 2 * np.sin(2 * t)
    assert bool(np.all(ok)) and np.abs(np.asarray(ys)[..., :2] - x).max() < 1e-10


def test_adaptive_solver_reports_failure():
    blow_up = lambda s, t: s**2  # noqa: E731  (s' = s², s(0) = 1 blows up at t = 1)
    ys, ok = adaptive_solve(blow_up, jnp.asarray([1.0]), jnp.linspace(0.0, 2.0, 5), max_steps=1000)
    assert not bool(ok)
    assert not np.all(np.isfinite(np.asarray(ys)))


def _stalling_solve(patience: int, max_steps: int) -> diffrax.Solution:
    """s' = (1.025 - t)^(-1/2): s stays finite (s(1) = 2(√1.025 - √0.025)) but the field is
    singular at t = 1.025, where Dopri8's steps shrink geometrically and time stalls."""
    ts = jnp.linspace(0.0, 2.0, 41)
    term = diffrax.ODETerm(lambda t, y, args: jnp.abs(1.025 - t) ** -0.5 * jnp.ones_like(y))
    inner = diffrax.ClipStepSizeController(diffrax.PIDController(rtol=1e-10, atol=1e-10), step_ts=ts)
    guard = StallGuard(inner, jnp.asarray(1e-9 * 0.05), patience)
    return diffrax.diffeqsolve(
        term,
        diffrax.Dopri8(),
        0.0,
        2.0,
        None,
        jnp.zeros(1),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=guard,
        max_steps=max_steps,
        throw=False,
    )


def test_stall_guard_stops_a_collapsed_step_size_early_and_keeps_the_states_before_it():
    guarded = _stalling_solve(STALL_PATIENCE, 20_000)
    unguarded = _stalling_solve(10**9, 20_000)
    # Without the guard the stall spends the whole budget; with it, the solve stops as failed
    # after the approach (91 accepted steps) and at most a few hundred more.
    assert unguarded.result == diffrax.RESULTS.max_steps_reached
    assert int(unguarded.stats["num_steps"]) == 20_000
    assert guarded.result == diffrax.RESULTS.dt_min_reached
    assert int(guarded.stats["num_steps"]) < 500
    exact = 2 * (np.sqrt(1.025) - np.sqrt(0.025))
    assert abs(float(guarded.ys[20, 0]) - exact) < 1e-8  # t = 1, before the singularity
    np.testing.assert_array_equal(np.asarray(guarded.ys[:21]), np.asarray(unguarded.ys[:21]))
    _, ok = adaptive_solve(
        lambda s, t: jnp.abs(1.025 - t) ** -0.5 * jnp.ones_like(s),
        jnp.zeros(1),
        jnp.linspace(0.0, 2.0, 41),
        rtol=1e-10,
        atol=1e-10,
        dense=False,
        max_steps=20_000,
    )
    assert not bool(ok)
