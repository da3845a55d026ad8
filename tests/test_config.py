import dataclasses

import pytest

from fhnn.config import Config, check_positive, frozen_config
from fhnn.errors import ConfigError
from fhnn.physics.scenarios import get_scenario, scenario_class


@frozen_config
class Solver(Config):
    rtol: float = 1e-10
    steps: int = 10
    verbose: bool = False

    def validate(self) -> None:
        check_positive(self, "rtol", "steps")


def test_unknown_field_is_named_with_suggestion():
    with pytest.raises(
        ConfigError,
        match=r"unknown parameter 'rtool' for Solver \(did you mean 'rtol'\?\); valid: rtol, steps, verbose",
    ):
        Solver(rtool=1.0)
    with pytest.raises(ConfigError, match="unknown parameter 'nope'"):
        Solver.from_dict({"nope": 1})


def test_frozen_and_keyword_only():
    s = Solver()
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.rtol = 1.0  # type: ignore[misc]
    with pytest.raises(ConfigError, match="keyword arguments only"):
        Solver(1e-3)  # type: ignore[misc]


def test_strings_are_converted_and_checked():
    s = Solver.from_dict({"rtol": "1e-12", "steps": "20", "verbose": "true"})
    assert (s.rtol, s.steps, s.verbose) == (1e-12, 20, True)
    with pytest.raises(ConfigError, match="Solver.steps must be an integer, got '2.5'"):
        Solver.from_dict({"steps": "2.5"})
    with pytest.raises(ConfigError, match="Solver.rtol must be a number, got 'abc'"):
        Solver.from_dict({"rtol": "abc"})
    with pytest.raises(ConfigError, match="Solver.rtol must be finite"):
        Solver.from_dict({"rtol": "nan"})
    with pytest.raises(ConfigError, match="Solver: rtol must be > 0, got -1.0"):
        Solver.from_dict({"rtol": "-1"})


def test_round_trip_through_dict():
    s = Solver(rtol=3e-9, steps=4)
    assert Solver.from_dict(s.to_dict()) == s
    assert s.replace(steps=5).steps == 5


def test_scenario_registry_rejects_unknown_names_and_values():
    with pytest.raises(ConfigError, match="unknown scenario 'vortex'; available: steady_vortex, "):
        scenario_class("vortex")
    with pytest.raises(ConfigError, match="did you mean 'gamma'"):
        get_scenario("steady_vortex", gama=3.0)
    with pytest.raises(ConfigError, match="scenario 'obstacle': radius must be > 0, got -0.5"):
        get_scenario("obstacle", radius=-0.5)
    with pytest.raises(ConfigError, match="r0_min .* must not exceed r0_max"):
        get_scenario("steady_vortex", r0_min=4.0, r0_max=3.0)
    assert get_scenario("steady_vortex", gamma="-2").gamma == -2.0  # signed: clockwise vortex
