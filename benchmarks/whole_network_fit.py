"""Does fitting the whole network on whole tracks take the flow's bias out, and what does it cost?

From the default run on an own-data choosing seed (``benchmarks/own_data.py --data-seed N``
first), every parameter of both nets is freed (``track_parameters(whole=True)``), not only the
output layers and constants the default whole-track fit moves, and the same objective (every
training piece rolled out from its fitted start state, the sum of squared position residuals)
is minimised matrix-free (:meth:`~fhnn.training.tracks.TrackFit.step_matrix_free`:
Levenberg–Marquardt with the start states eliminated, each step by lineax's conjugate gradients
on Jacobian-vector products). A dense solve in every parameter would need one forward-mode
tangent per parameter, tens of times the default fit's cost; optimistix's
``LevenbergMarquardt`` with ``lineax.CG`` stops at the first inner solve that reaches its step
cap, which at this conditioning is every one.

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
import own_data
from _common import DESIGN_DATA, check_choosing_seed, stamp
from jax.flatten_util import ravel_pytree

from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.training.tracks import ForecastScore, TrackFit, fitted_pieces, track_pieces

#: Where the record goes (a design note cites it).


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


def iterate(fit: TrackFit, steps: int, cg_steps: int) -> tuple[list[float], int]:
    """``steps`` matrix-free iterations of ``fit``; each one's seconds and how many were taken."""
    times: list[float] = []
    for _ in range(steps):
        began = time.perf_counter()
        result = fit.step_matrix_free(cg_steps)
        if not result.accepted:
            break
        times.append(time.perf_counter() - began)
        print(
            f"iteration {len(times)}: mean square {result.mean_square:.6e} m², λ {result.damping:.2e}, "
            f"{times[-1]:.1f} s",
            flush=True,
        )
    return times, len(times)


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
    free = model.track_parameters(whole=True)
    pieces = fitted_pieces(imported.train, cfg.track_samples, cfg.seed)[0]
    fit = TrackFit(model, free, pieces)
    default_p = int(ravel_pytree(eqx.filter(model, model.track_parameters()))[0].size)
    print(f"{fit.p} parameters ({default_p} in the default fit), {fit.n_tracks} pieces, {fit.n} residuals")
    before = {"train_mean_square_m2": fit.mean_square, **scores(model, free, imported, scored, cfg)}
    print("before", before, flush=True)

    seconds, steps = iterate(fit, args.steps, args.cg_steps)
    after = {"train_mean_square_m2": fit.mean_square, **scores(fit.model, free, imported, scored, cfg)}
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
