"""Shared helpers of the benchmark scripts."""

from __future__ import annotations

from pathlib import Path

from fhnn.data.dataset import Dataset, read_dataset, write_dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import get_scenario


def dataset(name: str, folder: Path) -> tuple[Dataset, Path]:
    """The default data set of scenario ``name``, simulated once into ``folder`` and reused."""
    path = folder / f"{name}.h5"
    if not path.exists():
        sc = get_scenario(name)
        write_dataset(simulate_dataset(sc, SimulationConfig.for_scenario(sc)), path)
    return read_dataset(path), path
