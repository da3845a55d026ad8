"""Shared fixtures. Importing fhnn switches JAX to float64 for the whole test session."""

from __future__ import annotations

import numpy as np
import pytest

import fhnn  # noqa: F401  (enables float64)
from fhnn.data.dataset import Dataset
from fhnn.data.simulate import SimulationConfig, simulate_dataset
from fhnn.physics.scenarios import SCENARIOS, get_scenario

#: Small data sets: every split present, short trajectories, fast to simulate.
SMALL = dict(n_traj=6, duration=3.0, test_duration=6.0)


def small_dataset(name: str, **overrides: object) -> Dataset:
    scenario = get_scenario(name)
    config = SimulationConfig.for_scenario(scenario, **{**SMALL, **overrides})
    return simulate_dataset(scenario, config)


@pytest.fixture(scope="session", params=sorted(SCENARIOS))
def scenario_dataset(request: pytest.FixtureRequest) -> Dataset:
    """A small simulated data set of every scenario (with actuation where the scenario has it)."""
    return small_dataset(request.param)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
