"""Simulator throughput: fhnn's batched JAX simulator against a loop of scipy's DOP853.

Same work on both sides: ``steady_vortex`` with random actuation, N trajectories × 20 s sampled
every 0.05 s, both at rtol = atol = TOL. Accuracy of both is measured against a much tighter solve
(scipy DOP853 at 1e-13, on the first 20 trajectories), so the speed-up is quoted at equal (or
better) accuracy. Usage::

    python benchmarks/simulate.py [--n 1000] [--tol 1e-12] [--scipy-n 1000]

``--scipy-n`` < ``--n`` times scipy on a subset and scales its time to N (said in the output).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from _common import printed_result
from scipy.integrate import solve_ivp

import fhnn
from fhnn.data.simulate import integrate
from fhnn.physics.actuation import sample_actuation
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.scenarios import get_scenario

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.reference import reference_actuation, reference_vector_field


def scipy_solve(f, y0, act, ts, tol):
    sol = solve_ivp(
        lambda t, s: f(t, s, reference_actuation(act, t)),
        (ts[0], ts[-1]),
        y0,
        method="DOP853",
        rtol=tol,
        atol=tol,
        t_eval=ts,
    )
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol.y.T


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="trajectories")
    parser.add_argument("--tol", type=float, default=1e-12, help="rtol = atol of both solvers")
    parser.add_argument("--scipy-n", type=int, default=None, help="trajectories timed for scipy")
    parser.add_argument("--duration", type=float, default=20.0)
    args = parser.parse_args()
    n, tol = args.n, args.tol
    scipy_n = min(args.scipy_n or n, n)

    scenario = get_scenario("steady_vortex")
    eom = EquationsOfMotion.of(scenario.flow(), scenario.body())
    rng = np.random.default_rng(0)
    y0 = scenario.sample_initial_states(rng, n)
    act = sample_actuation(rng, n)
    ts = 0.05 * np.arange(round(args.duration / 0.05) + 1)
    f = reference_vector_field(scenario)
    print(f"fhnn {fhnn.__version__}: steady_vortex, {n} trajectories x {args.duration:g} s, dt 0.05 s")
    print(f"both solvers at rtol = atol = {tol:g}")

    t0 = time.perf_counter()
    states, ok = integrate(eom, y0, act, ts, rtol=tol, atol=tol, batch_size=n)
    cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    states, ok = integrate(eom, y0, act, ts, rtol=tol, atol=tol, batch_size=n)
    warm = time.perf_counter() - t0
    assert ok.all()

    t0 = time.perf_counter()
    scipy_states = [scipy_solve(f, y0[i], act[i], ts, tol) for i in range(scipy_n)]
    scipy_time = (time.perf_counter() - t0) * n / scipy_n

    n_ref = min(20, scipy_n)
    ref = np.stack([scipy_solve(f, y0[i], act[i], ts, 1e-13) for i in range(n_ref)])
    err_fhnn = np.abs(states[:n_ref] - ref).max()
    err_scipy = np.abs(np.stack(scipy_states[:n_ref]) - ref).max()

    scaled = "" if scipy_n == n else f" (timed on {scipy_n}, scaled to {n})"
    print(
        f"fhnn (JAX, batched Dopri8) warm : {warm:8.2f} s  {n / warm:9.1f} traj/s  max error {err_fhnn:.1e} m"
    )
    print(f"fhnn incl. compilation         : {cold:8.2f} s  {n / cold:9.1f} traj/s")
    print(
        f"scipy solve_ivp DOP853 loop    : {scipy_time:8.2f} s  {n / scipy_time:9.1f} traj/s  "
        f"max error {err_scipy:.1e} m{scaled}"
    )
    print(f"speed-up warm: {scipy_time / warm:.1f}x   incl. compile: {scipy_time / cold:.1f}x (goal >= 20x)")
    print(
        f"errors against DOP853 at 1e-13 on {n_ref} trajectories: fhnn {err_fhnn:.1e}, scipy {err_scipy:.1e}"
    )


if __name__ == "__main__":
    if len(sys.argv) == 1:  # the default question: its printed answer is the result file
        with printed_result("simulate"):
            main()
    else:
        main()
