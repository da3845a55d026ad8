"""Time ``fhnn reproduce --quick`` as a user runs it, and check the report it writes.

Runs the README's main job in a new process with an empty compilation cache (what a fresh clone
gets after install), then once more into a new folder with the cache it left (what a second
reproduction of the same shapes gets), and prints:

- the wall time of each, against the 90 s target and the 179 s anchor (issue 12's starting point);
- where the cold run's time went: data sets (simulation, mostly compiling the solver), training
  and evaluation per model job (from each job's ``result.json``), and the rest (process start,
  imports, the report);
- the wall time of a rerun into the cold run's folder, which must run nothing and keep the report;
- whether both reports pass the checks of the slow test
  ``tests/test_reproduce.py::test_quick_reproduction_runs_every_table_and_renders``, which this
  script stands in for in the default test run (``tests/report_checks.py``: every table T1–T6 in
  three formats with the paper's column, every figure, the Markdown report, and the self-contained
  HTML rendered in headless Chromium with every image decoded).

With ``--seeds N`` it times the reproduction's seed axis instead: ``--quick --seeds N`` cold, with a
job per seed and with each cell's seeds as one task (``--set seeds_together=true``), their ratio,
and how far the two runs' validation losses part.

With ``--ray`` it runs ``--quick`` on the local executor and as Ray tasks on a cluster it starts
(``--ray local``; needs ``pip install 'fhnn[ray]'``), each with an empty compilation cache, and
checks that every job's metrics are bitwise those of the local run (both compile with
``fast_compile``'s XLA flags) and both reports pass (``benchmarks/results/quick_reproduction_ray.json``);
it stands in for the slow test
``tests/test_reproduce.py::test_ray_cluster_gives_the_numbers_of_the_local_executor``.

Usage::

    python benchmarks/quick_reproduction.py [--workers N] [--out DIR] [--seeds N | --ray]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

from _common import printed_result

import fhnn
from fhnn.experiments.grid import ReproduceConfig

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from tests.report_checks import check_report as report_checks  # noqa: E402

TARGET_SECONDS = 90.0
ANCHOR_SECONDS = 179.0


def run_quick(out: Path, cache: Path, workers: int | None, *extra: str, expect: str | None = None) -> float:
    """Wall seconds of ``fhnn reproduce --quick -o out [extra]`` with the compilation cache ``cache``
    (exits with the command's error if it fails, or if its summary lacks ``expect``)."""
    cmd = [sys.executable, "-m", "fhnn.cli.app", "reproduce", "--quick", "-o", str(out), "-q", *extra]
    if workers is not None:
        cmd += ["--workers", str(workers)]
    env = {**os.environ, "FHNN_JAX_CACHE": str(cache)}
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        sys.stderr.write(done.stderr)  # the whole of it: a worker that died says why
        sys.exit(f"fhnn reproduce --quick failed: {done.stderr.strip().splitlines()[-1:]}")
    if expect is not None and expect not in done.stdout:
        sys.exit(
            f"fhnn reproduce --quick into {out}: expected {expect!r} in its summary, got {done.stdout!r}"
        )
    return seconds


def check_report(out: Path) -> list[str]:
    """What fails the report checks in ``out`` (``tests/report_checks.py``; empty when it passes):
    the failed check's line."""
    try:
        report_checks(out, out.parent, set(ReproduceConfig.quick().scenario_table))
    except (AssertionError, OSError, ValueError, subprocess.SubprocessError) as e:
        line = traceback.extract_tb(e.__traceback__)[-1].line
        return [f"{out.name}: {line} {str(e)[:300]}".strip()]
    return []


def job_seconds(out: Path) -> dict[str, float]:
    """Training and evaluation seconds summed over the model jobs in ``out``, and the job count."""
    results = [json.loads(p.read_text()) for p in (out / "jobs").glob("*/result.json")]
    return {
        "jobs": len(results),
        "train": sum(r["train_seconds"] for r in results),
        "eval": sum(r["eval_seconds"] for r in results),
    }


def seed_axis(base: Path, workers: int | None, seeds: int) -> list[str]:
    """Time ``--quick --seeds seeds`` cold with a job per seed and with each cell's seeds together;
    print both, and the largest relative difference of a job's best validation loss between them.
    Returns what is missing from either report."""
    times = {}
    for together in (False, True):
        name = "together" if together else "apart"
        shutil.rmtree(base / name, ignore_errors=True)
        shutil.rmtree(base / f"jax-cache-{name}", ignore_errors=True)
        extra = ["--seeds", str(seeds), "--set", f"seeds_together={str(together).lower()}"]
        times[name] = run_quick(base / name, base / f"jax-cache-{name}", workers, *extra)
    print(f"fhnn reproduce --quick --seeds {seeds}, cold compilation cache")
    print(f"  a job per seed            {times['apart']:6.1f} s")
    print(
        f"  each cell's seeds as one  {times['together']:6.1f} s   (seeds_together) throughput ratio "
        f"{times['apart'] / times['together']:.2f}"
    )
    best = {}
    for name in ("apart", "together"):
        for path in (base / name / "jobs").glob("*/result.json"):
            r = json.loads(path.read_text())
            key = (
                r["spec"]["data"]["scenario"],
                r["spec"]["model"],
                r["spec"]["ablation"],
                r["spec"]["seed"],
            )
            best.setdefault(key, {})[name] = r["best_val"]
    pairs = [v for v in best.values() if len(v) == 2]
    gap = max(abs(v["together"] - v["apart"]) / abs(v["apart"]) for v in pairs)
    print(f"  {len(pairs)} jobs in both: best validation loss differs by at most {gap:.1e} relative")
    return check_report(base / "apart") + check_report(base / "together")


def ray_executor(base: Path, workers: int | None) -> list[str]:
    """Time ``--quick`` on the local executor and on a Ray cluster started for it, and compare
    every job's metrics bitwise. Returns what differs or fails the report checks."""
    times = {}
    for name, extra in (("local", ()), ("ray", ("--ray", "local"))):
        shutil.rmtree(base / name, ignore_errors=True)
        shutil.rmtree(base / f"jax-cache-{name}", ignore_errors=True)
        times[name] = run_quick(base / name, base / f"jax-cache-{name}", None if extra else workers, *extra)
    metrics = {
        name: {
            p.parent.name: json.dumps(json.loads(p.read_text())["spec_metrics"], sort_keys=True)
            for p in sorted((base / name / "jobs").glob("*/result.json"))
        }
        for name in times
    }
    print("fhnn reproduce --quick, cold compilation cache")
    print(f"  local executor          {times['local']:6.1f} s")
    print(f"  Ray tasks (--ray local) {times['ray']:6.1f} s")
    local, ray = metrics["local"], metrics["ray"]
    differ = sorted(job for job in local.keys() | ray.keys() if local.get(job) != ray.get(job))
    print(
        f"  {len(local)} jobs: metrics bitwise the same"
        if not differ
        else f"  FAILED: metrics differ for {differ}"
    )
    return differ + check_report(base / "local") + check_report(base / "ray")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--workers", type=int, default=None, help="as for fhnn reproduce (default: one per core)")
    p.add_argument("--out", type=Path, default=None, help="keep the two reproductions here")
    p.add_argument("--seeds", type=int, default=None, help="time the seed axis: N seeds apart and together")
    p.add_argument("--ray", action="store_true", help="the local executor against Ray tasks, bitwise")
    args = p.parse_args()
    base = Path(tempfile.mkdtemp(prefix="fhnn-quick-")) if args.out is None else args.out
    base.mkdir(parents=True, exist_ok=True)
    if args.seeds is not None or args.ray:
        print(f"fhnn {fhnn.__version__}, {os.cpu_count()} CPUs, workers {args.workers or 'one per core'}")
        if args.ray:
            missing = ray_executor(base, args.workers)
        else:
            missing = seed_axis(base, args.workers, args.seeds)
        print("  reports: every check passed" if not missing else f"  reports: FAILED {missing}")
        if args.out is None:
            shutil.rmtree(base, ignore_errors=True)
        if missing:
            sys.exit(1)
        return
    cache = base / "jax-cache"
    for sub in ("cold", "warm", "jax-cache"):
        shutil.rmtree(base / sub, ignore_errors=True)
    print(f"fhnn {fhnn.__version__}, {os.cpu_count()} CPUs, workers {args.workers or 'one per core'}")
    cold = run_quick(base / "cold", cache, args.workers)
    warm = run_quick(base / "warm", cache, args.workers)
    again = run_quick(base / "cold", cache, args.workers, expect="nothing changed, report kept")
    parts = job_seconds(base / "cold")
    print("fhnn reproduce --quick (every table and figure, 1 seed)")
    print(
        f"  cold compilation cache  {cold:6.1f} s   target {TARGET_SECONDS:.0f} s: "
        f"ratio {cold / TARGET_SECONDS:.2f}  anchor {ANCHOR_SECONDS:.0f} s: ratio {cold / ANCHOR_SECONDS:.2f}"
    )
    print(f"  warm compilation cache  {warm:6.1f} s   ratio to cold {warm / cold:.2f}")
    print(f"  rerun, nothing changed  {again:6.1f} s   (no job run, the report kept)")
    print(
        f"  cold run's {parts['jobs']} model jobs: training {parts['train']:.1f} s, evaluation "
        f"{parts['eval']:.1f} s of worker time (summed over workers)"
    )
    missing = check_report(base / "cold") + check_report(base / "warm")
    print("  reports: every check passed" if not missing else f"  reports: FAILED {missing}")
    if args.out is None:
        shutil.rmtree(base, ignore_errors=True)
    if missing:
        sys.exit(1)


if __name__ == "__main__":
    if len(sys.argv) == 1:  # the default question: its printed answer is the result file
        with printed_result("quick_reproduction"):
            main()
    elif sys.argv[1:] == ["--ray"]:  # the executors compared: its printed answer is a result file too
        with printed_result("quick_reproduction_ray"):
            main()
    else:
        main()
