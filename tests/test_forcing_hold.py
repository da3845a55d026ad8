"""A forcing table of thrusters that switch at its rows' times (``--forcing-hold previous``) is
held between rows and changes exactly at them in ``fhnn predict``'s forecast."""

from __future__ import annotations

import numpy as np
import pytest

from fhnn.data.table import held
from fhnn.errors import ConfigError
from fhnn.evaluation.predict import predict_tracks
from fhnn.models.registry import MODELS
from fhnn.training.run import RunConfig

from .conftest import small_dataset

START = np.array([0.8, 0.4, 0.05, -0.1])
F0, F1, F2 = np.array([0.4, 0.0]), np.array([-0.3, 0.5]), np.array([0.1, -0.2])


def _model():
    kind = MODELS["fhnn"]
    return kind.make(RunConfig().model, kind.arguments(small_dataset("steady_vortex")), 0)


def _constant(model, start, t0, duration, force) -> np.ndarray:
    """The state after ``duration`` s under a constant ``force``."""
    rows = {None: (np.array([t0, t0 + duration]), np.stack([force, force]))}
    got = predict_tracks(model, duration=duration, dt=duration / 50, initial=start, t0=t0, forcing_table=rows)
    return got.states[0, -1]


def test_a_held_forcing_table_switches_exactly_at_its_rows() -> None:
    model = _model()
    rows = {None: (np.array([0.0, 0.73, 1.46, 3.0]), np.stack([F0, F1, F2, F2]))}
    # the reference: three forecasts under constant forces, each from where the last one ended
    mid = _constant(model, START, 0.0, 0.73, F0)
    mid = _constant(model, mid, 0.73, 0.73, F1)
    want = _constant(model, mid, 1.46, 0.54, F2)
    step = predict_tracks(model, duration=2.0, dt=0.1, initial=START, forcing_table=held(rows, "previous"))
    assert step.t[0, -1] == pytest.approx(2.0)
    np.testing.assert_allclose(step.states[0, -1], want, atol=1e-7)
    ramp = predict_tracks(model, duration=2.0, dt=0.1, initial=START, forcing_table=held(rows, "linear"))
    assert np.max(np.abs(ramp.states[0, -1, :2] - want[:2])) > 100 * np.max(
        np.abs(step.states[0, -1, :2] - want[:2])
    )


def test_held_rows_are_a_step_and_a_bad_hold_is_refused() -> None:
    rows = {"a": (np.array([0.0, 2.0, 4.0]), np.stack([F0, F1, F2]))}
    t, f = held(rows, "previous")["a"]
    np.testing.assert_allclose(np.interp([1.0, 1.999, 2.0, 3.5], t, f[:, 0]), [F0[0], F0[0], F1[0], F1[0]])
    assert held(rows, "linear") is rows
    with pytest.raises(ConfigError, match="--forcing-hold must be one of linear, previous, got 'step'"):
        held(rows, "step")
