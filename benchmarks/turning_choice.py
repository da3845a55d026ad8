"""Choose a setting of the 3-DOF model on a choosing seed's validation loss.

Trains the default model and the model with one setting changed on each of ``--scenarios`` at
``--data-seed`` (a ``[turning]`` choosing seed of ``benchmarks/seeds.toml``; a confirming seed is
refused) and records each run's validation loss, its last training loss and its seconds, nothing
else: no test split and no truth is read. Writes ``docs/design/data/turning_choice_NAME_VALUE.json``.

    python benchmarks/turning_choice.py --data-seed 1 --set damping_inputs=speeds
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from _common import DESIGN_DATA, check_choosing_seed, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.data.planar import simulate_planar
from fhnn.models.planar import PlanarModelConfig
from fhnn.training.planar import PlanarTrainConfig, fit_planar


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=1)
    p.add_argument("--scenarios", default="turning_vortex")
    p.add_argument("--set", required=True, help="model.NAME=VALUE or training.NAME=VALUE (NAME=VALUE: model)")
    args = p.parse_args()
    check_choosing_seed("turning", args.data_seed)
    name, value = args.set.split("=", 1)
    part, _, key = name.rpartition(".")
    parsed = json.loads(value) if value[:1] in "0123456789-[{" else value
    runs = []
    for scenario in args.scenarios.split(","):
        data = simulate_planar(scenario, seed=args.data_seed)
        for label in ("default", args.set):
            model, training = PlanarModelConfig(), PlanarTrainConfig()
            if label != "default":
                if part == "training":
                    training = training.replace(**{key: parsed})
                else:
                    model = model.replace(**{key: parsed})
            fit = fit_planar(data, model, training)
            run = {
                "scenario": scenario,
                "setting": label,
                "val_loss": fit.val_loss,
                "last_train_loss": fit.history[-1][2],
                "seconds": fit.seconds,
            }
            runs.append(run)
            print(json.dumps(run), flush=True)
    record = {**stamp(), "data_seed": args.data_seed, "seed_role": "choosing", "setting": args.set}
    record["runs"] = runs
    target = DESIGN_DATA / f"turning_choice_{key}_{str(parsed).lower()}.json"
    target.write_text(json.dumps(record, indent=1))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
