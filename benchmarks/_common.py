"""Shared helpers of the benchmark scripts."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario
from fhnn.runtime import provenance
from fhnn.stamps import file_digests, result_files


def dataset(name: str, folder: Path, seed: int | None = None) -> tuple[Dataset, Path]:
    """The data set of scenario ``name`` (its default data seed, or ``seed``), simulated once into
    ``folder`` and reused."""
    path = folder / (f"{name}.h5" if seed is None else f"{name}_seed{seed}.h5")
    if not path.exists():
        sc = get_scenario(name)
        write_dataset(simulate_dataset(sc, SimulationConfig.for_scenario(sc, seed=seed)), path)
    return read_dataset(path), path


def seconds_per_call(fn: Callable[[], Any], repeats: int) -> float:
    """Mean wall time of ``fn()`` over ``repeats`` calls after one warm call."""
    jax.block_until_ready(fn())
    t0 = time.perf_counter()
    for _ in range(repeats):
        out = fn()
    jax.block_until_ready(out)
    return (time.perf_counter() - t0) / repeats


#: The provenance as the script started, with the files its digest covers
#: (:func:`fhnn.stamps.result_files`) and each one's digest (:func:`fhnn.stamps.file_digests`,
#: by which the result is judged against the files its script runs): the code it runs is the code
#: it loaded then, not what the source tree holds when it ends (it may have changed during a run
#: of hours).
_FILES = result_files()
_STARTED = {**provenance(), "files": _FILES, "file_digests": file_digests(_FILES)}


def stamp() -> dict:
    """The provenance a result file records (:func:`fhnn.runtime.provenance`, taken as the
    script started; its ``date`` when the result is written, ``started`` when the script
    started): its ``commit`` (with ``+dirty`` where the package's source had changes) at the
    top, for the docs' list."""
    record = {**_STARTED, "started": _STARTED["date"], "date": provenance()["date"]}
    commit = record["commit"] or "unknown"
    return {"commit": commit + ("+dirty" if record["dirty"] else ""), "provenance": record}


#: Where the design notes' records go (choices and diagnostics, not shown results).
DESIGN_DATA = Path(__file__).resolve().parents[1] / "docs" / "design" / "data"

SEEDS_FILE = Path(__file__).with_name("seeds.toml")


def seeds(benchmark: str, role: str) -> list[int]:
    """The data seeds of ``benchmark`` (a table of ``benchmarks/seeds.toml``) for ``role``,
    ``"choosing"`` or ``"confirming"``."""
    import tomllib

    table = tomllib.loads(SEEDS_FILE.read_text())[benchmark]
    return list(table[role])


def seed_role(benchmark: str, seed: int) -> str:
    """Whether data seed ``seed`` is ``"choosing"`` or ``"confirming"`` for ``benchmark`` in
    ``benchmarks/seeds.toml``, or ``"unlisted"``."""
    return next((r for r in ("choosing", "confirming") if seed in seeds(benchmark, r)), "unlisted")


def check_choosing_seed(benchmark: str, seed: int) -> None:
    """Stop a script that chooses settings when ``seed`` is one of the confirming seeds."""
    if seed in seeds(benchmark, "confirming"):
        raise SystemExit(
            f"error: data seed {seed} confirms {benchmark} choices (benchmarks/seeds.toml); choose on "
            f"{seeds(benchmark, 'choosing')}"
        )


#: Where the benchmarks' result files live (each stamped by :func:`stamp`).
RESULTS = Path(__file__).resolve().parent / "results"


class printed_result:
    """Keep what a benchmark prints as its result file: ``with printed_result("NAME"):`` copies
    stdout to ``benchmarks/results/NAME.json`` as ``{"commit", "provenance", "argv", "output"}``,
    written when the block ends without an error."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.lines: list[str] = []

    def write(self, text: str) -> int:
        self.lines.append(text)
        return self.stdout.write(text)

    def flush(self) -> None:
        self.stdout.flush()

    def __enter__(self) -> printed_result:
        import sys

        self.stdout, sys.stdout = sys.stdout, self
        return self

    def __exit__(self, kind, value, traceback) -> None:
        import json
        import sys

        sys.stdout = self.stdout
        if kind is None:
            record = {**stamp(), "argv": sys.argv[1:], "output": "".join(self.lines)}
            (RESULTS / f"{self.name}.json").write_text(json.dumps(record, indent=1))
            print(f"wrote benchmarks/results/{self.name}.json")
