"""Does it learn a body that turns? The 3-DOF model on its own scenarios, at the defaults.

For each of ``turning_vortex`` and ``turning_time_varying_vortex`` (docs/spec.md §7): simulate the
data set of ``--data-seed`` (noise-free), train with :func:`fhnn.api.planar.train_turning`'s
defaults, and compare with the truth (:func:`fhnn.api.planar.evaluate_turning`): RMSE of position
and heading at 5 s on the test split, the added masses, the damping over the visited relative
velocities and the flow near the training positions, each against issue 71's target. Which data
seeds may choose and which only confirm: ``benchmarks/seeds.toml`` (``[turning]``).

    python benchmarks/turning.py --data-seed 3
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from _common import RESULTS, seed_role, stamp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fhnn.api.planar import evaluate_turning, simulate_turning, train_turning

SCENARIOS = ("turning_vortex", "turning_time_varying_vortex")
#: Issue 71's targets: RMSE(pos) [m] and heading [rad] at 5 s; relative errors of the added
#: masses, the damping (L2 per axis) and the flow (L2).
TARGETS = {"rmse_pos": 1e-4, "rmse_heading": 1e-3, "added_mass": 0.02, "damping": 0.05, "flow": 0.01}


def run(name: str, seed: int, folder: Path) -> dict:
    start = time.perf_counter()
    data = simulate_turning(name, seed=seed)

    def progress(phase: str, step: int, steps: int, loss: float) -> None:
        if step % 500 == 0 or step == steps:
            print(f"  {name} {phase} {step}/{steps} train loss {loss:.3e}", flush=True)

    fit = train_turning(data, out=folder / name, progress=progress)
    report = evaluate_turning(fit.model, data)
    report["train_seconds"] = fit.seconds
    report["val_loss"] = fit.val_loss
    report["wall_seconds"] = time.perf_counter() - start
    return report


def met(report: dict) -> dict[str, bool]:
    """Whether each target is met."""
    return {
        "rmse_pos": report["forecast"]["rmse_pos"] <= TARGETS["rmse_pos"],
        "rmse_heading": report["forecast"]["rmse_heading"] <= TARGETS["rmse_heading"],
        "added_mass": max(m["rel_error"] for m in report["added_mass"].values()) <= TARGETS["added_mass"],
        "damping": max(report["damping"][a]["rel_l2"] for a in ("surge", "sway", "yaw"))
        <= TARGETS["damping"],
        "flow": report["flow"]["rel_l2"] <= TARGETS["flow"],
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data-seed", type=int, default=3)
    p.add_argument("--result", default=None, help="result file name (default turning_seedN)")
    args = p.parse_args()
    role = seed_role("turning", args.data_seed)
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in SCENARIOS:
            report = run(name, args.data_seed, Path(tmp))
            report["met"] = met(report)
            runs[name] = report
            f = report["forecast"]
            masses = ", ".join(f"{k} {v['rel_error']:.2%}" for k, v in report["added_mass"].items())
            damping = ", ".join(f"{a} {report['damping'][a]['rel_l2']:.2%}" for a in ("surge", "sway", "yaw"))
            print(
                f"{name}: RMSE(pos)@5s {f['rmse_pos']:.3g} m, heading {f['rmse_heading']:.3g} rad; "
                f"masses {masses}; damping {damping}; flow {report['flow']['rel_l2']:.3%}; "
                f"trained in {report['train_seconds']:.0f} s",
                flush=True,
            )
    record = {**stamp(), "data_seed": args.data_seed, "seed_role": role, "targets": TARGETS, "runs": runs}
    target = RESULTS / f"{args.result or f'turning_seed{args.data_seed}'}.json"
    target.write_text(json.dumps(record, indent=1))
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
