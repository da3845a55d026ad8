"""Are the Laplace intervals right where the model can hold the truth exactly?

FHNN set to a simulated body's truth (``tests/exact_fhnn.py``: the solid-body vortex, constant
added masses and drag, the fitted parameters the coefficient net's output biases, the constant
``c_l`` and the far field), four actuated 3 s training tracks. Each of ``--draws`` noise draws
adds 1 mm of Gaussian noise to the positions, fits the parameters by the whole-track fit from the
truth (``--iterations`` Levenberg–Marquardt iterations) and takes the Laplace interval of each
coefficient at one ``(r, σ)`` from the fit's curvature (:mod:`fhnn.training.curvature`). Over the
draws: the spread of the estimates against the mean Laplace sd (an honest sd gives a ratio near
1; with 20 draws its standard error is about 16 %) and the share of draws whose 90 % interval holds
the truth. The noise draws are this script's own; no setting was chosen on them.

    python benchmarks/laplace_exact.py [--draws 20] [--iterations 15]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np
from _common import RESULTS, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.evaluation.recovery import COEFFICIENT_NAMES, coefficients_at
from fhnn.training.curvature import FLOOR, track_curvature
from fhnn.training.tracks import TrackFit
from tests.exact_fhnn import exact_data, exact_model, exact_scenario

NOISE = 1e-3  # [m]
POINT = jnp.asarray([[1.0, 0.5]])  # (r, σ) [m, m/s]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=20)
    p.add_argument("--iterations", type=int, default=15)
    p.add_argument("--seed", type=int, default=300, help="first noise seed")
    args = p.parse_args()
    scenario = exact_scenario()
    ds = exact_data(scenario)
    model, free = exact_model(ds, scenario, Path(tempfile.mkdtemp()) / "run")
    truth = np.array([scenario.m_a_base, scenario.m_a_base, scenario.c_q, scenario.c_l])

    def quantities(m):
        return coefficients_at(m.eom.coefficients, POINT)[0]

    draws = []
    start = time.perf_counter()
    for k in range(args.draws):
        rng = np.random.default_rng(args.seed + k)
        states = ds.train.states.copy()
        states[..., :2] += NOISE * rng.normal(size=states[..., :2].shape)
        split = dataclasses.replace(ds.train, states=states)
        fit = TrackFit(model, free, split)
        for _ in range(args.iterations):
            if not fit.step().accepted:
                break
        found = track_curvature(fit.model, split, free).intervals(quantities)
        draws.append({key: np.asarray(found[key]).tolist() for key in ("value", "sd", "lo", "hi")})
        print(f"draw {k}: estimates {np.round(found['value'], 4)}, sd {np.round(found['sd'], 4)}", flush=True)
    value, sd = (np.array([d[key] for d in draws]) for key in ("value", "sd"))
    lo, hi = (np.array([d[key] for d in draws]) for key in ("lo", "hi"))
    rows = {
        name: {
            "true": float(truth[i]),
            "mean_estimate": float(value[:, i].mean()),
            "spread": float(value[:, i].std(ddof=1)),
            "mean_laplace_sd": float(sd[:, i].mean()),
            "spread_over_sd": float(value[:, i].std(ddof=1) / sd[:, i].mean()),
            "holds": float(np.mean((lo[:, i] <= truth[i]) & (truth[i] <= hi[:, i]))),
        }
        for i, name in enumerate(COEFFICIENT_NAMES)
    }
    print(f"{args.draws} draws of {NOISE * 1e3:g} mm noise, {args.iterations} iterations, floor {FLOOR:g}")
    head = ("true", "mean", "spread", "Laplace sd", "spread/sd", "holds")
    print("  " + " " * 6 + " ".join(f"{h:>10s}" for h in head))
    for name, r in rows.items():
        print(
            f"  {name:6s} {r['true']:10.4g} {r['mean_estimate']:10.4g} {r['spread']:10.3g} "
            f"{r['mean_laplace_sd']:10.3g} {r['spread_over_sd']:10.2f} {r['holds']:10.0%}"
        )
    record = {
        **stamp(),
        "draws": args.draws,
        "iterations": args.iterations,
        "noise": NOISE,
        "floor": FLOOR,
        "wall_seconds": time.perf_counter() - start,
        "coefficients": rows,
        "per_draw": draws,
    }
    target = RESULTS / "laplace_exact.json"
    target.write_text(json.dumps(record, indent=1))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
