"""Does a learned 3-DOF model hold a body on station as well as the true one?

Simulates ``turning_vortex`` at ``--data-seed``, trains the 3-DOF model with the defaults (as
``benchmarks/turning.py`` does) and runs ``examples/station_keeping.py`` on it: the RMS distance
from the station under model-predictive control with the learned model against the same controller
with the true equations (issue 71's target: a ratio of at most 1.2), with the drift without thrust
beside them.

    python benchmarks/station_keeping.py --data-seed 3
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from _common import RESULTS, seed_role, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

import station_keeping

from fhnn.api.planar import simulate_turning, train_turning

TARGET = 1.2


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=3)
    p.add_argument("--seconds", type=float, default=30.0)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        fit = train_turning(simulate_turning("turning_vortex", seed=args.data_seed), out=Path(tmp) / "run")
        result = station_keeping.main(["--run", str(Path(tmp) / "run"), "--seconds", str(args.seconds)])
    record = {
        **stamp(),
        "data_seed": args.data_seed,
        "seed_role": seed_role("turning", args.data_seed),
        "target_ratio": TARGET,
        "train_seconds": fit.seconds,
        **result,
    }
    target = RESULTS / f"station_keeping_seed{args.data_seed}.json"
    target.write_text(json.dumps(record, indent=1))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
