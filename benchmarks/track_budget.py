"""How many samples should the whole-track fit hold? Chosen on the own-data choosing seeds'
validation tracks, from one ``own_data.py`` run per seed and budget (``train.track_samples``).

The default budget, 25,000 samples, holds all 49 training tracks of an own-data table (~20,000
samples); a smaller one keeps a seeded subset of them (:func:`fhnn.training.tracks.track_pieces`)
and each whole-track iteration's forward-mode passes shrink with it. For each budget this reads,
per data seed, the validation forecast that does not depend on the budget: ``own_data.py``'s
``val_forecasts.origins`` (``fhnn predict`` from the first second of a piece starting every 2 s
of each validation track, RMSE(pos) at 5 s against its observations), over the same at the
default.

The rule, fixed in ``benchmarks/seeds.toml`` before the runs it reads were made: the smallest
budget whose geometric mean ratio over the choosing seeds is at most :data:`FORECAST_SLACK`.
Only that ratio chooses. The record keeps beside it each run's training time (the runs shared
the 2 cores, two to four at a time), the tracks its fit held, and its errors against the simulator's truth
(coefficients, total drag, flow), which choose nothing.

    python benchmarks/own_data.py --data-seed N --skip-speed --out DIR/sN_default
    python benchmarks/own_data.py --data-seed N --skip-speed --out DIR/sN_B --set train.track_samples=B
    python benchmarks/track_budget.py --out DIR        # N = 0, 1, 2; B = 12500, 6250

With ``--confirm B`` it reads fresh seed :data:`CONFIRM_SEED`'s runs at the default and at the
chosen ``B`` instead (``DIR/s5_default``, ``DIR/s5_B``), and records the same ratio beside the
held-out (test) tracks' forecast error from their first second against the truth, whatever they
show (``docs/design/data/track_budget_confirming.json``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from _common import DESIGN_DATA, seeds, stamp

#: The budget of ``fhnn train``'s defaults, then the candidates, largest first.
DEFAULT = 25_000
CANDIDATES = (12_500, 6_250)
#: Largest accepted geometric-mean ratio of the validation forecast to the default's.
FORECAST_SLACK = 1.01
#: The fresh own-data seed that confirms a chosen budget (``benchmarks/seeds.toml``).
CONFIRM_SEED = 5


def _run(folder: Path, seed: int, budget: int, test: bool = False) -> dict:
    """The scores of ``own_data.py``'s run of data seed ``seed`` at ``budget`` in ``folder``;
    with ``test``, also the held-out tracks' forecast error at 5 s against the truth."""
    tag = "defaults" if budget == DEFAULT else f"traintrack_samples{budget}"
    result = json.loads((folder / f"result_seed{seed}_{tag}.json").read_text())
    history = json.loads((folder / f"run_seed{seed}_{tag}" / "run.json").read_text())["history"]
    tracks = [r for r in history if r.get("phase") == "tracks"]
    return {
        "commit": result["commit"],
        "val_forecast_5s": result["val_forecasts"]["origins"]["rmse_pos_vs_observed"]["5"],
        "val_forecasts": result["val_forecasts"]["origins"]["trajectories"],
        "train_seconds": result["train_seconds"],
        "fit_tracks": tracks[0]["tracks"] if tracks else 0,
        "fit_iterations": len(tracks),
        "truth": {
            "coefficients_mean_rel": result["coefficients_mean_rel"],
            "drag_mean_rel": result["drag_mean_rel"],
            "flow_rel_l2": result["flow_rel_l2"],
            **({"test_forecast_5s": result["test_forecasts"]["rmse_pos_vs_truth"]["5"]} if test else {}),
        },
    }


def time_normal_equations(folder: Path, seed: int, budgets: tuple[int, ...]) -> dict[str, float]:
    """Wall seconds of one Gauss–Newton system (the whole-track iteration's forward-mode passes,
    :meth:`~fhnn.training.tracks.TrackFit._normal_equations`, after a first call that compiles)
    at each budget, on the pieces a run of seed ``seed``'s default run would fit, its model."""
    import time

    import jax

    from fhnn.data.dataset import read_dataset
    from fhnn.training.run import Run
    from fhnn.training.tracks import TrackFit, fitted_pieces

    run = Run.load(folder / f"run_seed{seed}_defaults")
    data = read_dataset(folder / f"track_seed{seed}.h5")
    model = run.state.best_model
    seconds = {}
    for budget in budgets:
        pieces, _ = fitted_pieces(data.train, budget, run.train_config.seed)
        fit = TrackFit(model, model.track_parameters(), pieces)
        jax.block_until_ready(fit._normal_equations())
        began = time.perf_counter()
        jax.block_until_ready(fit._normal_equations())
        seconds[str(budget)] = time.perf_counter() - began
    return seconds


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, required=True, help="folder of the sN_B run folders")
    p.add_argument("--confirm", type=int, default=None, metavar="B", help="confirm budget B on seed 5")
    p.add_argument(
        "--time", action="store_true", help="also time one Gauss-Newton system per budget (run alone)"
    )
    args = p.parse_args()
    confirming = args.confirm is not None
    if confirming:
        assert CONFIRM_SEED in seeds("own_data", "confirming"), "seed 5 confirms (benchmarks/seeds.toml)"
    data_seeds = [CONFIRM_SEED] if confirming else seeds("own_data", "choosing")
    candidates = (args.confirm,) if confirming else CANDIDATES
    budgets = (DEFAULT, *candidates)
    folder = lambda s, b: args.out / f"s{s}_{'default' if b == DEFAULT else b}"  # noqa: E731
    runs = {str(b): {str(s): _run(folder(s, b), s, b, confirming) for s in data_seeds} for b in budgets}
    ratios, chosen = {}, DEFAULT
    for b in candidates:
        score = lambda b, s: runs[str(b)][str(s)]["val_forecast_5s"]  # noqa: E731
        per_seed = [score(b, s) / score(DEFAULT, s) for s in data_seeds]
        gmean = float(np.exp(np.mean(np.log(per_seed))))
        ratios[str(b)] = {"per_seed": per_seed, "gmean": gmean}
        if gmean <= FORECAST_SLACK:
            chosen = b  # candidates run largest first: the last one within the slack is the smallest
    record = {
        **stamp(),
        "benchmark": "own_data",
        "seed_role": "confirming" if confirming else "choosing",
        "data_seeds": data_seeds,
        "default": DEFAULT,
        "forecast_slack": FORECAST_SLACK,
        "runs": runs,
        "ratios": ratios,
        "chosen": args.confirm if confirming else chosen,
        **({"confirmed": chosen == args.confirm} if confirming else {}),
    }
    if args.time:
        first = data_seeds[0]
        record["normal_equations_seconds"] = time_normal_equations(folder(first, DEFAULT), first, budgets)
        record["timed_on"] = first
    target = DESIGN_DATA / f"track_budget_{'confirming' if confirming else 'choosing'}.json"
    target.write_text(json.dumps(record, indent=1))
    for b, r in ratios.items():
        cells = " ".join(f"{x:.4f}" for x in r["per_seed"])
        print(f"track_samples {b:>6}: validation forecast / default's {cells}, gmean {r['gmean']:.4f}")
    said = f"confirmed: {chosen == args.confirm}" if confirming else f"chosen: train.track_samples = {chosen}"
    print(f"{said}; wrote {target}")


if __name__ == "__main__":
    main()
