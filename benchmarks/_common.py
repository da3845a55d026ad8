"""Shared helpers of the benchmark scripts."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax

from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario


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


ROOT = Path(__file__).resolve().parents[1]


def commit() -> str:
    """The commit of the working tree, with ``+dirty`` where ``src`` has changes."""

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], capture_output=True, text=True, cwd=ROOT).stdout.strip()

    return git("rev-parse", "HEAD") + ("+dirty" if git("status", "--porcelain", "src") else "")
