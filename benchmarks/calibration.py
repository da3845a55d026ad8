"""Are ``fhnn inspect``'s 90 % intervals calibrated? Coverage over many independent own-data tables.

Each data seed is the own-data benchmark's recipe (``benchmarks/own_data.py``: the actuated
``steady_vortex`` body tracked at 0.05 s ± 30 % with 1 mm noise, 5 % of rows missing), imported and
trained as ``fhnn train --seeds N`` trains it by default (bootstrap members), its intervals those
of ``fhnn inspect`` (:func:`fhnn.experiments.exports.ensemble_intervals`). Per coefficient and
ratio, over the data sets: the share whose interval of the typical value holds the true one
(target 85–95 %), the median relative width, the median relative error of the members' median
and that error in units of the interval's half-width over 1.645 (an interval that is an honest
±1.645 sd puts this near the normal's median |z|, 0.67).

With ``--method laplace`` each data set is trained once (``fhnn train`` with no options) and
its intervals are the Laplace ones from the whole-track fit's curvature
(:func:`fhnn.experiments.laplace.laplace_tables`), for each eigenvalue floor of :data:`FLOORS`:
the choosing seeds choose the floor (:data:`fhnn.training.curvature.FLOOR`; their record goes
to ``docs/design/data``), the confirming ones confirm it (``benchmarks/results``). The rule,
fixed before the choosing run: the largest floor (the narrowest intervals) under which every
coefficient and ratio holds the truth in at least 9 of the 10 choosing data sets; where no floor
does, the smallest, and the target is reported missed. A quantity
whose interval is withheld (wider than its value) does not hold. Each data set's result is kept
in its folder, so a rerun picks up where one stopped.

The data seeds are ``benchmarks/seeds.toml``'s ``[calibration]`` table; ``--role`` picks the
choosing or the confirming ones. Each data set is one independent job: with ``--ray ADDRESS``
they run as Ray tasks on that cluster (``ray start --head`` makes a local one), else one after
another. ``--fast`` shrinks data and training to minutes in all, to check the machinery (its
numbers say nothing).

    python benchmarks/calibration.py --role choosing [--members 3 | --method laplace]
        [--no-forcing] [--ray auto]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from _common import DESIGN_DATA, RESULTS, seeds, stamp

#: Where a choosing run's record goes (the docs' design notes cite it).
#: The eigenvalue floors ``--method laplace`` compares (relative to the largest eigenvalue).
FLOORS = (1e-16, 1e-15, 1e-14, 1e-13, 1e-12)
#: Training settings of ``--fast`` (``fhnn train --set``), besides ``--steps``.
FAST_SETS = ("model.width=8", "train.val_every=10", "train.track_steps=2")


def one(
    data_seed: int, out: Path, members: int, no_forcing: bool, fast: bool, method: str = "ensemble"
) -> dict:
    """Import, train and score the intervals of data seed ``data_seed`` in ``out``: per name,
    ``ensemble_intervals``' row (``median``, ``lo``, ``hi``, ``true``, ``coverage`` over the
    points, errors), or with ``method`` ``"laplace"`` per floor of :data:`FLOORS` the rows of
    :func:`~fhnn.experiments.laplace.laplace_tables`; and the training time. Kept in ``out`` as
    ``result_<method>.json`` and read back from there on a rerun."""
    import own_data

    from fhnn.data.dataset import read_dataset
    from fhnn.experiments.exports import ensemble_intervals
    from fhnn.experiments.laplace import laplace_tables
    from fhnn.training.ensemble import member_folders
    from fhnn.training.run import Run

    out.mkdir(parents=True, exist_ok=True)
    tag = f"{'_noforce' if no_forcing else ''}{'_fast' if fast else ''}"
    kept = out / f"result_{method}{'' if method == 'laplace' else members}{tag}.json"
    if kept.exists():
        return json.loads(kept.read_text())
    size = {"n_traj": 10, "duration": 4.0} if fast else {}
    fine, _, _, data, _ = own_data.make_data(out, data_seed, no_forcing=no_forcing, **size)
    sets = ["--steps", "20", *[x for s in FAST_SETS for x in ("--set", s)]] if fast else []
    scored = None
    start = time.perf_counter()
    if method == "laplace":
        folder = out / f"run_seed{data_seed}{tag}"
        own_data.run_cli("train", str(data), "-o", str(folder), "-q", *sets)
        seconds = time.perf_counter() - start
        scored = own_data.with_truth(read_dataset(data), fine)
        run = Run.load(folder)
        tables = laplace_tables(
            run.state.best_model, scored, run.train_config, scored.equations().coefficients, FLOORS
        )
        rows = {f"{floor:g}": table for floor, table in (tables or {}).items()}
    else:
        ens = out / f"ens{members}_seed{data_seed}{tag}"
        own_data.run_cli("train", str(data), "-o", str(ens), "--seeds", str(members), "-q", *sets)
        seconds = time.perf_counter() - start
        scored = own_data.with_truth(read_dataset(data), fine)
        eoms = [Run.load(f).state.best_model.eom for f in member_folders(ens)]
        rows = ensemble_intervals(eoms, scored, scored.equations())
    found = {"data_seed": data_seed, "train_seconds": seconds, "rows": rows}
    kept.write_text(json.dumps(found, default=float))
    return found


def laplace_summary(results: list[dict]) -> dict[str, dict[str, dict[str, float]]]:
    """Per floor and name: ``holds`` (share of data sets whose interval holds the true median),
    ``withheld`` (share whose interval was wider than the value), ``weak`` (share marked weak),
    ``median_rel_width`` (over the data sets with an interval), ``median_rel_error`` of the
    median and ``median_z`` (the error over the sd; an honest sd puts it near 0.67)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for floor in results[0]["rows"]:
        out[floor] = {}
        for name in results[0]["rows"][floor]:
            rows = [r["rows"][floor][name] for r in results]
            given = [r for r in rows if r["determined"]]
            error = [abs(r["median"] - r["true"]) / abs(r["true"]) for r in rows]
            out[floor][name] = {
                "holds": float(np.mean([bool(r["inside"]) for r in rows])),
                "withheld": float(np.mean([not r["determined"] for r in rows])),
                "weak": float(np.mean([r["weak"] for r in rows])),
                "median_rel_width": float(np.median([(r["hi"] - r["lo"]) / abs(r["median"]) for r in given]))
                if given
                else float("nan"),
                "median_rel_error": float(np.median(error)),
                "median_z": float(np.median([abs(r["median"] - r["true"]) / r["sd"] for r in given]))
                if given
                else float("nan"),
            }
    return out


def summary(results: list[dict]) -> dict[str, dict[str, float]]:
    """Per name: ``holds`` (share of data sets whose interval of the typical value holds the true
    one), ``median_rel_width``, ``median_rel_error`` of the members' median and ``median_z`` (the
    error over the half-width / 1.645), and ``pointwise_coverage`` (median over the data sets of
    the share of covered points holding the truth)."""
    names = results[0]["rows"].keys()
    out = {}
    for name in names:
        rows = [r["rows"][name] for r in results]
        true = np.array([r["true"] for r in rows])
        lo, hi, med = (np.array([r[k] for r in rows]) for k in ("lo", "hi", "median"))
        half = np.maximum((hi - lo) / 2, 1e-300)
        out[name] = {
            "holds": float(np.mean((lo <= true) & (true <= hi))),
            "median_rel_width": float(np.median([r["rel_width"] for r in rows])),
            "median_rel_error": float(np.median(np.abs(med - true) / np.abs(true))),
            "median_z": float(np.median(np.abs(med - true) / (half / 1.645))),
            "pointwise_coverage": float(np.median([r["coverage"] for r in rows])),
        }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--role", choices=["choosing", "confirming"], required=True)
    p.add_argument("--members", type=int, default=3)
    p.add_argument(
        "--method",
        choices=["ensemble", "laplace"],
        default="ensemble",
        help="the members' intervals (fhnn train --seeds N) or one run's Laplace intervals per floor",
    )
    p.add_argument("--no-forcing", action="store_true")
    p.add_argument("--fast", action="store_true", help="tiny data and training: checks the machinery only")
    p.add_argument("--ray", default=None, help="address of a Ray cluster to run the data sets on")
    p.add_argument("--limit", type=int, default=None, help="only the first N data seeds of the role")
    p.add_argument("--out", type=Path, default=Path("benchmarks/_calibration"))
    args = p.parse_args()
    data_seeds = seeds("calibration", args.role)[: args.limit]
    out = args.out.resolve()
    members = 1 if args.method == "laplace" else args.members
    jobs = [(s, out / f"seed{s}", members, args.no_forcing, args.fast, args.method) for s in data_seeds]
    start = time.perf_counter()
    if args.ray:
        import ray

        # the workers import this folder's scripts (fhnn itself must be installed on every node)
        here = Path(__file__).resolve().parent
        env = {"working_dir": str(here), "excludes": ["_*/", "results/"]}  # scripts, not outputs
        ray.init(address=args.ray, runtime_env=env, include_dashboard=False, log_to_driver=False)
        task = ray.remote(num_cpus=1)(one)
        results = ray.get([task.remote(*job) for job in jobs])
    else:
        results = []
        for job in jobs:
            results.append(one(*job))
            print(f"data seed {job[0]}: trained in {results[-1]['train_seconds']:.0f} s", flush=True)
    print(
        f"{len(results)} data sets ({args.role} seeds {data_seeds}), {args.method}, {members} member(s) each"
    )
    if args.method == "laplace":
        table = laplace_summary(results)
        for floor, rows in table.items():
            head = ("holds", "withheld", "weak", "rel. width", "rel. error", "|z|")
            print(f" floor {floor}: " + " ".join(f"{h:>10s}" for h in head))
            for name, r in rows.items():
                print(
                    f"  {name:14s} {r['holds']:10.0%} {r['withheld']:10.0%} {r['weak']:10.0%} "
                    f"{r['median_rel_width']:10.1%} {r['median_rel_error']:10.2%} {r['median_z']:10.2f}"
                )
    else:
        table = summary(results)
        print(f"  {'':14s} {'holds':>6s} {'rel. width':>10s} {'rel. error':>10s} {'|z|':>6s} {'points':>6s}")
        for name, r in table.items():
            print(
                f"  {name:14s} {r['holds']:6.0%} {r['median_rel_width']:10.1%} {r['median_rel_error']:10.2%} "
                f"{r['median_z']:6.2f} {r['pointwise_coverage']:6.0%}"
            )
    record = {
        **stamp(),
        "seed_role": args.role,
        "data_seeds": data_seeds,
        "method": args.method,
        "members": members,
        "no_forcing": args.no_forcing,
        "fast": args.fast,
        "wall_seconds": time.perf_counter() - start,
        "summary": table,
        "data_sets": results,
    }
    method = "_laplace" if args.method == "laplace" else ""
    name = f"calibration{method}_{args.role}{'_noforce' if args.no_forcing else ''}"
    # --fast numbers are not results; a choosing run is the record of a choice (design data),
    # a confirming one a result the docs show at the current code
    folder = args.out if args.fast else RESULTS if args.role == "confirming" else DESIGN_DATA
    target = folder / f"{name}.json"
    target.write_text(json.dumps(record, indent=1, default=float))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
