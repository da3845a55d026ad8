"""Does fitting the whole network on whole tracks take the flow's bias out, and what does it cost?

From the default run on an own-data choosing seed (``benchmarks/own_data.py --data-seed N``
first), every parameter of both nets is freed — not only the output layers and constants the
default whole-track fit moves (:meth:`~fhnn.models.fhnn.FHNN.track_parameters`) — and the same
objective (every training piece rolled out from its fitted start state, the sum of squared
position residuals) is minimised matrix-free: Levenberg–Marquardt with the start states
eliminated and each step solved by lineax's conjugate gradients, one Jacobian-vector and one
transposed product through every track's rollout per inner iteration (optimistix's
``LevenbergMarquardt`` with ``lineax.CG`` stops at the first inner solve that reaches its step
cap, which at this conditioning is every one) (a dense solve in every parameter
would need one forward-mode tangent per parameter, tens of times the default fit's cost).

Printed and written (``--result``): parameters, cost per outer iteration, the training pieces'
misfit, the validation forecasts and validation tracks' misfit as the default run's forecast
guard scores them, and — a record, not a choice — the coefficients' and flow's errors against
the simulator's truth, each before and after.

    python benchmarks/whole_network_fit.py --data-seed 0 [--steps 8] [--cg-steps 40]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import own_data
from _common import check_choosing_seed, stamp
from jax.flatten_util import ravel_pytree

from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.training.tracks import ForecastScore, TrackFit, fitted_pieces, track_pieces

#: Where the record goes (a design note cites it).
DESIGN_DATA = Path(__file__).resolve().parents[1] / "docs" / "design" / "data"


def whole_network(model) -> object:
    """The filter of every parameter :meth:`track_parameters` frees plus every array of both
    nets' MLPs."""
    free = model.track_parameters()
    for pick in (lambda m: m.eom.coefficients.mlp, lambda m: m.eom.flow.mlp):
        free = eqx.tree_at(pick, free, replace=jax.tree.map(eqx.is_inexact_array, pick(model)))
    return free


def scores(model, free, imported, scored, cfg) -> dict:
    """Validation and truth scores of ``model``."""
    held = TrackFit(model, free, track_pieces(imported.val, cfg.track_samples, cfg.seed + 6)[0])
    forecasts = ForecastScore(model, free, imported.val, cfg.track_samples, cfg.seed + 7)
    theta = held.theta
    coef = own_data.recovery_scores(coefficient_recovery(model.coefficients, scored))
    return {
        "val_forecast_m": float(forecasts(theta)),
        "val_track_mean_square_m2": float(held.mean_square),
        "coefficients_mean_rel": coef["coefficients_mean_rel"],
        "drag_mean_rel": coef["drag_mean_rel"],
        "flow_rel_l2": float(flow_recovery(model.flow, scored)["rel_l2"]),
    }


def levenberg_marquardt(fit: TrackFit, tracks: tuple, steps: int, cg_steps: int):
    """``steps`` Levenberg–Marquardt iterations in every parameter of ``fit`` with the start
    states eliminated: each solves ``(JᵀPJ + λI) δ = −JᵀPr`` (``P`` projects out each track's
    start-state directions) by lineax's conjugate gradients, at most ``cg_steps`` products
    ``v ↦ JᵀPJv`` (one JVP and one transposed JVP through every rollout), then moves the start
    states to their Gauss–Newton optimum under the step. Returns the parameters, start states,
    the seconds of each outer iteration and how many were taken."""
    n_tracks = fit.z.shape[0]

    def rows(th, zz):
        return fit._resid(th, zz, *tracks).reshape(n_tracks, -1)

    def pieces(theta, z):
        r, lin = jax.linearize(lambda th: rows(th, z), theta)
        back = jax.linear_transpose(lin, theta)
        jz = fit._jz(theta, z, *tracks).reshape(n_tracks, -1, 4)  # each track's start-state block
        hz = jnp.einsum("nki,nkj->nij", jz, jz)
        hz = hz + 1e-12 * jnp.trace(hz, axis1=1, axis2=2)[:, None, None] * jnp.eye(4)

        def project(u):
            w = jnp.linalg.solve(hz, jnp.einsum("nki,nk->ni", jz, u)[..., None])[..., 0]
            return u - jnp.einsum("nki,ni->nk", jz, w)

        return r, lin, back, jz, hz, project

    @jax.jit
    def curvature_scale(theta, z):
        _, lin, _, _, _, project = pieces(theta, z)
        probes = jax.random.rademacher(jax.random.PRNGKey(0), (4, theta.size), dtype=theta.dtype)
        return jnp.mean(jax.vmap(lambda v: jnp.sum(project(lin(v)) ** 2))(probes))

    @jax.jit
    def solve(theta, z, lam):
        r, lin, back, jz, hz, project = pieces(theta, z)
        g = back(project(r))[0]
        op = lx.FunctionLinearOperator(
            lambda v: back(project(lin(v)))[0] + lam * v,
            jax.eval_shape(lambda: theta),
            lx.positive_semidefinite_tag,
        )
        step = lx.linear_solve(op, -g, lx.CG(rtol=1e-6, atol=0.0, max_steps=cg_steps), throw=False).value
        moved = r + lin(step)
        dz = -jnp.linalg.solve(hz, jnp.einsum("nki,nk->ni", jz, moved)[..., None])[..., 0]
        return step, dz

    theta, z = fit.theta, fit.z
    value = float(jnp.sum(rows(theta, z) ** 2))
    lam = 1e-3 * float(curvature_scale(theta, z))  # a thousandth of the mean curvature
    times: list[float] = []
    taken = 0
    for _ in range(steps):
        began = time.perf_counter()
        while True:
            step, dz = solve(theta, z, lam)
            new = float(jnp.sum(rows(theta + step, z + dz) ** 2))
            if new < value:
                theta, z, value, lam = theta + step, z + dz, new, lam / 3
                taken += 1
                break
            lam *= 4
            if lam > 1e20:
                return theta, z, times, taken
        times.append(time.perf_counter() - began)
        print(f"iteration {taken}: mean square {value / fit.n:.6e} m², λ {lam:.2e}, {times[-1]:.1f} s")
    return theta, z, times, taken


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=Path("benchmarks/_own_data"))
    p.add_argument("--steps", type=int, default=8, help="outer Levenberg–Marquardt iterations")
    p.add_argument("--cg-steps", type=int, default=40, help="conjugate-gradient iterations per solve")
    p.add_argument("--result", default=None, help="write docs/design/data/RESULT.json")
    args = p.parse_args()
    check_choosing_seed("own_data", args.data_seed)
    imported, scored, run = own_data.trained_run(args.out, args.data_seed)
    cfg = run.config.train
    model = run.state.best_model
    free = whole_network(model)
    pieces = fitted_pieces(imported.train, cfg.track_samples, cfg.seed)[0]
    fit = TrackFit(model, free, pieces)
    tracks = fit._tracks(slice(None))
    default_p = int(ravel_pytree(eqx.filter(model, model.track_parameters()))[0].size)
    print(f"{fit.p} parameters ({default_p} in the default fit), {fit.n_tracks} pieces, {fit.n} residuals")
    before = {"train_mean_square_m2": fit.mean_square, **scores(model, free, imported, scored, cfg)}
    print("before", before, flush=True)

    theta, z, seconds, steps = levenberg_marquardt(fit, tracks, args.steps, args.cg_steps)
    train_ms = float(jnp.sum(fit._resid(theta, z, *tracks) ** 2)) / fit.n
    after_model = fit.model_at(theta)
    after = {"train_mean_square_m2": train_ms, **scores(after_model, free, imported, scored, cfg)}
    print("after", after, flush=True)
    record = {
        **stamp(),
        "data_seed": args.data_seed,
        "parameters": fit.p,
        "pieces": fit.n_tracks,
        "residuals": fit.n,
        "cg_steps": args.cg_steps,
        "outer_steps": steps,
        "seconds_per_outer_step": seconds,
        "solver": "Levenberg–Marquardt, start states eliminated, lineax CG on JᵀPJ + λI",
        "before": before,
        "after": after,
    }
    print(json.dumps({k: v for k, v in record.items() if k not in ("before", "after", "provenance")}))
    if args.result:
        (DESIGN_DATA / f"{args.result}.json").write_text(json.dumps(record, indent=1, default=float))


if __name__ == "__main__":
    main()
