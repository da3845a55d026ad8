"""Every model on the same data, with the same optimiser budget, scored by the same evaluator.

For ``solid_body_vortex`` (the paper's configuration) and ``steady_vortex`` (with actuation), trains
FHNN, Neural ODE, HNN, LNN, DHN, dissipative HNN (Adam, ``--steps`` steps each, same batch size and
schedule) and fits SINDy, then prints RMSE / ADE / FDE of positions at 1 s and 5 s (docs/spec.md §5, and in
the paper's averaging over t = 0, 1, …, H), with diverged rollouts counted and shown as diverged.
The paper's own numbers (its data) at 5 s: HNN 1.77 m, LNN 5.85e10 m, DHN 1.02 m, FHNN 6.09e-4 m.

    python benchmarks/baselines.py [--steps 3000] [--only solid|steady] [--models fhnn,node,...]
    python benchmarks/baselines.py --search

``--search`` gives every gradient-trained model, FHNN included, the same plan search: the
learning rate (1e-3, 3e-3, 1e-2) × the networks' width (32, 64, 128), ``--steps`` Adam steps each,
the candidate with the lowest validation loss kept (the test split is read only for the kept
candidate's table); it writes ``benchmarks/results/baselines_searched.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from _common import RESULTS, dataset, stamp

import fhnn
from fhnn.evaluation.evaluate import evaluate
from fhnn.models.registry import MODELS
from fhnn.training.plans import PAPER_TRAIN
from fhnn.training.run import Run, RunConfig

#: The plan search of ``--search``: every candidate, every gradient-trained model.
SEARCH_LR = (1e-3, 3e-3, 1e-2)
SEARCH_WIDTH = (32, 64, 128)
PAPER_5S = {"hnn": 1.77, "lnn": 5.85e10, "dhn": 1.02, "fhnn": 6.09e-4}


def fmt(m: dict, key: str) -> str:
    if m["diverged"] == m["n_traj"]:
        return "diverged"
    value = f"{m[key]:.2e}"
    return value + (f" ({m['diverged']} div.)" if m["diverged"] else "")


def train_run(folder: Path, ds, path: Path, config: RunConfig) -> Run:
    """A run of ``config`` in ``folder``, trained (resumed, or reused, where one is there)."""
    if (folder / "run.json").exists():
        run = Run.load(folder, expect_model=config.kind)
    else:
        run = Run.create(folder, ds, config, data_path=path)
    run.train(ds)
    return run


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=3000)
    p.add_argument("--only", choices=["solid", "steady"], default=None)
    p.add_argument("--models", default=",".join(MODELS))
    p.add_argument("--out", type=Path, default=Path("benchmarks/_baselines"))
    p.add_argument("--search", action="store_true", help="choose lr × width per model on its val loss")
    args = p.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    models = [m for m in args.models.split(",") if m]
    names = {
        "solid": ["solid_body_vortex"],
        "steady": ["steady_vortex"],
        None: ["solid_body_vortex", "steady_vortex"],
    }
    report: dict = {}
    print(f"fhnn {fhnn.__version__}: {args.steps} Adam steps per model (batch 256), SINDy fitted")
    for name in names[args.only]:
        ds, path = dataset(name, args.out)
        report[name] = {}
        for kind in models:
            folder = args.out / f"{name}_{kind}"
            t0 = time.perf_counter()
            candidates = {}
            if args.search and MODELS[kind].fit is None:
                for lr in SEARCH_LR:
                    for width in SEARCH_WIDTH:
                        model = MODELS[kind].default_config().replace(width=width)
                        train = PAPER_TRAIN.replace(steps=args.steps, val_every=500, lr=lr)
                        config = RunConfig(kind=kind, model=model, train=train)
                        where = folder.with_name(f"{folder.name}_lr{lr:g}_w{width}")
                        run = train_run(where, ds, path, config)
                        candidates[f"lr={lr:g} width={width}"] = (run.state.best_val, run)
                        print(f"    {kind} lr={lr:g} width={width}: val {run.state.best_val:.3e}", flush=True)
                chosen = min(candidates, key=lambda c: candidates[c][0])
                run = candidates[chosen][1]
            else:
                chosen = "default"
                config = RunConfig(kind=kind, train=PAPER_TRAIN.replace(steps=args.steps, val_every=500))
                run = train_run(folder, ds, path, config)
            secs = time.perf_counter() - t0
            res = {"chosen": chosen, "val_loss": {c: v for c, (v, _) in candidates.items()}}
            for zero in (False, True):
                out = evaluate(run.state.best_model, ds, [1, 5], include_zero=zero)["horizons"]
                res["paper_avg" if zero else "spec"] = out
            report[name][kind] = {"seconds": secs, **res}
            print(f"  {name:18s} {kind:6s} trained in {secs:6.0f} s ({chosen})", flush=True)
        print(f"\n{name}: position errors [m] (averaged over t = 1..H, docs/spec.md §5; diverged counted)")
        heads = [f"{k} {h}s" for h in (1, 5) for k in ("RMSE", "ADE", "FDE")]
        print(f"  {'model':6s} " + " ".join(f"{h:>18s}" for h in heads) + "  paper RMSE 5s")
        for kind in models:
            r = report[name][kind]["spec"]
            cells = [fmt(r[h], k) for h in ("1", "5") for k in ("rmse_pos", "ade", "fde")]
            paper = f"{PAPER_5S[kind]:.2e}" if kind in PAPER_5S else "-"
            print(f"  {kind:6s} " + " ".join(f"{c:>18s}" for c in cells) + f"  {paper}")
        fh = report[name].get("fhnn", {}).get("spec", {}).get("1", {}).get("rmse_pos", np.nan)
        nd = report[name].get("node", {}).get("spec", {}).get("1", {}).get("rmse_pos", np.nan)
        print(f"  Neural ODE / FHNN RMSE at 1 s: {nd / fh:.1f}x (paper: 42x)\n")
    (args.out / "report.json").write_text(json.dumps(report, indent=1, default=float))
    if args.only is None and set(models) == set(MODELS):  # the whole comparison: a result
        if args.search:
            how = (
                f"every gradient-trained model (FHNN included): the paper's training (Adam, batch 256), "
                f"{args.steps} steps, with the learning rate in {list(SEARCH_LR)} and the width in "
                f"{list(SEARCH_WIDTH)} chosen on its own validation loss; SINDy fitted once"
            )
            name = "baselines_searched.json"
        else:
            how = f"every model: the paper's training (Adam, batch 256), {args.steps} steps, its default size"
            name = "baselines.json"
        record = {**stamp(), "steps": args.steps, "trained_as": how, **report}
        (RESULTS / name).write_text(json.dumps(record, indent=1, default=float))
        print(f"wrote benchmarks/results/{name}")


if __name__ == "__main__":
    main()
