"""How the whole-track fit's cost grows with tracks and parameters, and what optimistix's
Levenberg–Marquardt (dense QR, or matrix-free CG on the normal equations or LSMR, from
lineax) costs on the same problem.

The problem is exactly representable: a truth that differs from a fresh FHNN in the fitted
parameters only (the model's :meth:`track_parameters`, 2 % relative steps), its tracks on the
actuated ``steady_vortex`` rolled out by the truth from the data's start states, the fit started
from the fresh model and from start states 1 mm and 1 mm/s off. Each solver runs until the mean
square residual falls below 1e-18 m² or ``--steps`` iterations; the table gives the parameters
(model + 4 per track), compile time, time per iteration and where it ended.

    python benchmarks/track_fit_solvers.py [--tracks 8,32] [--widths 8,32] [--steps 30] [--duration 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx
from _common import RESULTS, stamp
from jax.flatten_util import ravel_pytree

from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario
from fhnn.training.run import Run, RunConfig
from fhnn.training.tracks import TrackFit

TARGET = 1e-18  # mean square per axis [m²]


def problem(n_tracks: int, width: int, duration: float = 3.0):
    """A fresh FHNN, its fitted parameters' filter, and exact tracks of a truth 2 % away."""
    sc = get_scenario("steady_vortex")
    config = SimulationConfig.for_scenario(sc, n_traj=n_tracks + 2, duration=duration, test_duration=duration)
    config = config.replace(split=(n_tracks / (n_tracks + 2), 1 / (n_tracks + 2), 1 / (n_tracks + 2)))
    ds = simulate_dataset(sc, config)
    base = RunConfig()
    rc = RunConfig(model=base.model.replace(width=width), train=base.train)
    model = Run.create(Path(tempfile.mkdtemp()) / "run", ds, rc).skeleton()
    free = model.track_parameters()
    params, static = eqx.partition(model, free)
    theta, unravel = ravel_pytree(params)
    step = 0.02 * jax.random.normal(jax.random.PRNGKey(7), theta.shape) * (jnp.abs(theta) + 0.1)
    truth = eqx.combine(unravel(theta + step), static)
    # the truth's tracks as the fit rolls them out (RK4, a step per sample): its residuals
    # against zero positions, from the data's start states
    sp = ds.train
    blank = dataclasses.replace(sp, states=sp.states * np.r_[0.0, 0.0, 1.0, 1.0])
    rolled = TrackFit(truth, free, blank)
    positions = rolled._resid(rolled.theta, jnp.asarray(sp.states[:, 0]), *rolled._tracks(slice(None)))
    states = np.concatenate([np.asarray(positions), sp.states[..., 2:]], axis=-1)
    exact = dataclasses.replace(sp, states=states)
    return model, free, exact


def start(fit: TrackFit, exact) -> None:
    fit.z = jnp.asarray(exact.states[:, 0] + np.r_[1e-3, -1e-3, 1e-3, 1e-3])
    fit.value = fit._total_cost(fit.theta, fit.z)


def run_trackfit(model, free, exact, steps: int) -> dict:
    fit = TrackFit(model, free, exact)
    start(fit, exact)
    t0 = time.perf_counter()
    fit.step()  # compiles the Jacobian programs
    first = time.perf_counter() - t0
    t0, n = time.perf_counter(), 1
    while fit.mean_square > TARGET and n < steps:
        if not fit.step().accepted:
            break
        n += 1
    per = (time.perf_counter() - t0) / max(n - 1, 1)
    return {"first_s": first, "per_iter_s": per, "iterations": n, "mean_square": fit.mean_square}


def run_optimistix(model, free, exact, steps: int, solver_name: str) -> dict:
    fit = TrackFit(model, free, exact)
    start(fit, exact)
    tracks = fit._tracks(slice(None))
    resid = fit._resid

    def fn(y, args):
        return resid(y[0], y[1], *tracks).ravel()

    linear = {
        "qr": lambda: lx.QR(),
        "cg": lambda: lx.Normal(lx.CG(rtol=1e-10, atol=1e-14)),
        "lsmr": lambda: lx.LSMR(rtol=1e-10, atol=1e-14),
    }[solver_name]()
    solver = optx.LevenbergMarquardt(rtol=1e-14, atol=1e-14, linear_solver=linear)
    y0 = (fit.theta, fit.z)

    @eqx.filter_jit
    def solve(y0, max_steps):
        return optx.least_squares(fn, solver, y0, max_steps=max_steps, throw=False)

    t0 = time.perf_counter()
    jax.block_until_ready(solve(y0, 1).value)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    sol = solve(y0, steps)
    jax.block_until_ready(sol.value)
    wall = time.perf_counter() - t0
    n = int(sol.stats["num_steps"])
    ms = float(jnp.sum(fn(sol.value, None) ** 2)) / fit.n
    return {"first_s": first, "per_iter_s": wall / max(n, 1), "iterations": n, "mean_square": ms}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tracks", default="8,32")
    p.add_argument("--widths", default="8,32")
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--solvers", default="trackfit,qr,cg,lsmr")
    p.add_argument("--duration", type=float, default=3.0, help="length of each track [s]")
    p.add_argument("--result", default="track_fit_solvers", help="benchmarks/results/RESULT.json")
    args = p.parse_args()
    rows = []
    for n_tracks in map(int, args.tracks.split(",")):
        for width in map(int, args.widths.split(",")):
            model, free, exact = problem(n_tracks, width, args.duration)
            n_theta = int(ravel_pytree(eqx.filter(model, free))[0].size)
            n_res = 2 * int(exact.mask.sum())
            for name in args.solvers.split(","):
                if name == "trackfit":
                    out = run_trackfit(model, free, exact, args.steps)
                else:
                    out = run_optimistix(model, free, exact, args.steps, name)
                row = {"tracks": exact.n_traj, "width": width, "model_params": n_theta, "residuals": n_res}
                row |= {"solver": name, **out}
                rows.append(row)
                print(
                    f"tracks {row['tracks']:3d} width {width:3d} p {n_theta:4d}+{4 * row['tracks']:4d} "
                    f"n {n_res:6d} {name:8s} first {out['first_s']:6.1f} s  "
                    f"per iter {out['per_iter_s']:7.3f} s"
                    f"  {out['iterations']:3d} it  mean sq {out['mean_square']:.2e} m²",
                    flush=True,
                )
    record = {**stamp(), "target_mean_square": TARGET, "steps": args.steps, "duration_s": args.duration}
    record["rows"] = rows
    (RESULTS / f"{args.result}.json").write_text(json.dumps(record, indent=1))
    print(f"wrote benchmarks/results/{args.result}.json")


if __name__ == "__main__":
    main()
