"""The reproduction's default plan on a confirming data seed: FHNN on all six scenarios.

    python benchmarks/reproduction_confirm.py [--data-seed N] [--out DIR]

Runs ``fhnn reproduce --config FILE`` with ``models = ["fhnn"]``, ``ablations = []`` and
``[data] seed = N`` (N: the confirming seed of ``benchmarks/seeds.toml``'s ``[reproduction]``
table) and keeps its ``tables.json``, with the seed and its role, as
``benchmarks/results/reproduction_seedN.json``. The seed is run with the settings as they stand
and reported whatever it gives.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

from _common import RESULTS, seed_role, seeds


def main() -> None:
    (confirming, *_) = seeds("reproduction", "confirming")
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=confirming, help="data seed (default: %(default)s)")
    p.add_argument("--out", type=Path, default=None, help="reproduction folder (default: a temporary one)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp) / "reproduction"  # a new folder: reproduce refuses a used one
        settings = Path(tmp) / "confirm.toml"
        settings.write_text(f'models = ["fhnn"]\nablations = []\n\n[data]\nseed = {args.data_seed}\n')
        subprocess.run(["fhnn", "reproduce", "-o", str(out), "-q", "--config", str(settings)], check=True)
        record = json.loads((out / "tables" / "tables.json").read_text())
    record = {
        "commit": record["provenance"]["commit"],
        **record,
        "data_seed": args.data_seed,
        "seed_role": seed_role("reproduction", args.data_seed),
    }
    path = RESULTS / f"reproduction_seed{args.data_seed}.json"
    path.write_text(json.dumps(record, indent=1))
    print(f"wrote {path.relative_to(RESULTS.parents[1])}")


if __name__ == "__main__":
    main()
