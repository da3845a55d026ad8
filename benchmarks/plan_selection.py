"""Choose a training plan on the validation split: train FHNN with given settings, score the val split.

Plans are chosen on validation numbers only and confirmed on a data seed not used while tuning
(the test split is never read here). For each scenario and data seed it prints the wall time, the
best validation loss, why Adam stopped (if it did), RMSE(pos) of val rollouts at 1 s and 5 s (the
val trajectories' length allowing), and the coefficient and flow recovery (which compares with the
simulator's truth, not with held-out data), and the validation loss at every record.

``--true-flow`` is a diagnosis, not a plan: the FHNN's stream net is replaced by the simulator's
true flow and only the coefficient net trains (same phases), which shows how well the
coefficients could be recovered if the flow were known exactly.

Usage::

    python benchmarks/plan_selection.py --scenario steady_vortex --data-seed 1 \\
        --set train.warmup_steps=400 --set train.steps=12000 [--plan adam-polish] [--true-flow] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import equinox as eqx
from _common import check_choosing_seed, dataset

from fhnn.evaluation.evaluate import evaluate
from fhnn.evaluation.recovery import coefficient_recovery, flow_recovery
from fhnn.runtime import default_cache_dir, use_compilation_cache
from fhnn.training.plans import get_plan, is_noisy, noisy_model_settings
from fhnn.training.run import Run, RunConfig
from fhnn.training.trainer import Trainer, TrainState


def _value(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def _train_under_true_flow(model, ds, config: RunConfig) -> TrainState:
    """The phases of :meth:`Run.train` (warm-up, Adam, polish) on ``model`` with its flow replaced
    by the data set's true flow (a flow without parameters: only the coefficients train)."""
    model = eqx.tree_at(lambda m: m.eom.flow, model, ds.equations().flow)
    trainer = Trainer(config.train, ds.train, ds.val)
    state = trainer.run(trainer.warmup(trainer.init(model)))
    return trainer.polish(state) if config.train.lbfgs_steps else state


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", required=True)
    p.add_argument("--data-seed", type=int, default=1)
    p.add_argument("--plan", default=None, help="a named plan to start from")
    p.add_argument("--set", action="append", default=[], help="NAME=VALUE (dotted, as fhnn train)")
    p.add_argument("--out", type=Path, default=Path("benchmarks/_plan_selection"))
    p.add_argument("--true-flow", action="store_true", help="train the coefficients under the true flow")
    args = p.parse_args()
    use_compilation_cache(default_cache_dir())
    args.out.mkdir(parents=True, exist_ok=True)
    check_choosing_seed("reproduction", args.data_seed)
    ds, path = dataset(args.scenario, args.out, args.data_seed)
    settings = get_plan(args.plan or "adam").settings("fhnn")  # no plan: the paper's settings
    if is_noisy(ds):
        settings.update({f"model.{k}": v for k, v in noisy_model_settings("fhnn").items()})
    settings.update({k: _value(v) for k, v in (s.split("=", 1) for s in args.set)})
    config = RunConfig().with_settings(settings)
    tag = "_".join(f"{k.split('.')[-1]}{v}" for k, v in sorted(settings.items()) if not isinstance(v, list))
    folder = args.out / f"run_{args.scenario}_s{args.data_seed}_{abs(hash(tag)) % 10**8}"
    t0 = time.perf_counter()
    if args.true_flow:
        state = _train_under_true_flow(Run.create(folder, ds, config, data_path=path).skeleton(), ds, config)
    else:
        state = Run.create(folder, ds, config, data_path=path).train(ds, save=False)
    secs = time.perf_counter() - t0
    horizons = [h for h in (1, 5) if h <= ds.val.t[-1] + 1e-9]
    res = evaluate(state.best_model, ds, horizons, split="val")["horizons"]
    out = {
        "scenario": args.scenario,
        "data_seed": args.data_seed,
        "settings": settings,
        "true_flow": args.true_flow,
        "seconds": round(secs, 1),
        "best_val": state.best_val,
        "stopped": state.stopped,
        "val_rmse_pos": {h: res[h]["rmse_pos"] for h in res},
    }
    if ds.actuation != "none":
        coef = coefficient_recovery(state.best_model.coefficients, ds)
        out["coef_max_rel"] = {k: coef[k]["max_rel"] for k in ("m_ax", "m_ay", "c_q", "c_l")}
        out["flow_rel_l2"] = flow_recovery(state.best_model.flow, ds)["rel_l2"]
        out["c_q_by_sigma"] = [
            [round(b["sigma_lo"], 4), round(b["quadratic_share"], 3), round(b["c_q"], 4)]
            for b in coef["_by_sigma"]
        ]
    # the validation loss at every record: where each phase got to, and whether the polish overfits
    history = state.history
    out["trace"] = [(h["step"], h.get("phase", "adam"), float(f"{h['val_total']:.3g}")) for h in history]
    print(json.dumps(out))


if __name__ == "__main__":
    main()
