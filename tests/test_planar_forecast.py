"""A turning body's start state fitted to observed poses (:mod:`fhnn.evaluation.planar_start`)
and forecasts from it (:mod:`fhnn.api.planar_forecast`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from fhnn.data.planar import simulate_planar
from fhnn.errors import ConfigError
from fhnn.evaluation.planar_start import fit_start_states


@pytest.fixture(scope="module")
def planar_data():
    """The data of ``tests/test_planar.py``'s command-line test (its compiled programs serve)."""
    return simulate_planar("turning_vortex", n_traj=6, duration=1.0, test_duration=2.0, seed=4)


def _fit(data, start, pose, noise, observed=None):
    test = data.splits["test"]
    return fit_start_states(
        data.truth().equations(), start, test.t, pose, test.residual(), test.thrust, noise, observed=observed
    )


def test_the_true_equations_fit_the_true_start_to_noisy_poses(planar_data) -> None:
    """From a start whose velocity is 5 cm/s and 0.05 rad/s off, the true equations fit the
    noise-free poses back to the true start; on noisy poses the misfit is the noise's (a mean
    square of about one per scaled residual) and the velocity error is far under the guess's."""
    test = planar_data.splits["test"]
    truth = test.states_clean[:, 0]
    guess = truth + np.array([0.0, 0.0, 0.0, 0.05, -0.05, 0.05])
    exact, rollout = _fit(planar_data, guess, test.states_clean[..., :3], (1e-3, 1e-3))
    np.testing.assert_allclose(exact, truth, rtol=0, atol=1e-6)
    np.testing.assert_allclose(rollout, test.states_clean, rtol=0, atol=1e-6)
    rng = np.random.default_rng(0)
    sigma = 1e-3
    noisy = test.states_clean[..., :3] + rng.normal(0.0, sigma, test.states_clean[..., :3].shape)
    fitted, rollout = _fit(planar_data, guess, noisy, (sigma, sigma))
    velocity_error = np.abs(fitted[:, 3:] - truth[:, 3:])
    assert velocity_error.max() < 0.2 * 0.05, velocity_error
    scaled = (rollout[..., :3] - noisy) / sigma
    samples, parameters = scaled.size, fitted.size
    assert 0.6 < np.sum(scaled**2) / (samples - parameters) < 1.5


def test_padded_samples_do_not_count_and_bad_settings_are_refused(planar_data) -> None:
    """A sample outside ``observed`` may hold anything; too few samples or a bad noise level is
    one line."""
    test = planar_data.splits["test"]
    pose = np.array(test.states_clean[..., :3], copy=True)
    observed = np.ones(pose.shape[:2], bool)
    observed[:, -3:] = False
    pose[:, -3:] = 1e3  # junk where nothing is observed
    fitted, _ = _fit(planar_data, test.states_clean[:, 0] + 0.01, pose, (1e-3, 1e-3), observed)
    np.testing.assert_allclose(fitted, test.states_clean[:, 0], rtol=0, atol=1e-6)
    with pytest.raises(ConfigError, match="the noise levels must be positive"):
        _fit(planar_data, test.states_clean[:, 0], pose, (0.0, 1e-3))
    few = np.zeros_like(observed)
    few[:, :2] = True
    with pytest.raises(ConfigError, match="at least 3 observed samples per track"):
        _fit(planar_data, test.states_clean[:, 0], pose, (1e-3, 1e-3), few)


def test_a_track_whose_fitted_rollout_diverges_keeps_its_smoothed_start(planar_data, monkeypatch) -> None:
    """Where the fitted start's rollout does not reach a track's end, that track (and no other)
    starts from the smoothed estimate, and a warning names it."""
    import fhnn.api.planar_forecast as forecast
    from fhnn.data.planar_table import _smoothed, observed_table, read_planar_table

    tracks = read_planar_table(pd.DataFrame(observed_table(planar_data))).trajectories
    poses, rates, noise_pos, noise_psi = _smoothed(tracks, "kalman")
    model = planar_data.truth().equations()
    smoothed, _ = forecast._end_states(model, tracks, poses, rates, (noise_pos, noise_psi), 0.0)
    fitted, _ = forecast._end_states(model, tracks, poses, rates, (noise_pos, noise_psi), 10.0)
    real = forecast.fit_start_states

    def first_diverges(*args, **kwargs):
        start, rollout = real(*args, **kwargs)
        rollout = rollout.copy()
        rollout[0, 1:] = np.nan
        return start, rollout

    monkeypatch.setattr(forecast, "fit_start_states", first_diverges)
    with pytest.warns(UserWarning, match=f"diverged for track\\(s\\) {tracks[0].traj_id};"):
        mixed, _ = forecast._end_states(model, tracks, poses, rates, (noise_pos, noise_psi), 10.0)
    np.testing.assert_array_equal(mixed[0], smoothed[0])
    np.testing.assert_array_equal(mixed[1:], fitted[1:])
    assert not np.allclose(fitted[0], smoothed[0], rtol=0, atol=1e-9)
