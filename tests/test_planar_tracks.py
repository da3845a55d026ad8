"""The turning body's windowed whole-track fit (fhnn.training.planar_tracks): windows, the
residuals of the true equations, a fit that lowers its objective, the guard."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.data.planar import simulate_planar
from fhnn.errors import ConfigError
from fhnn.models.planar import PlanarModelConfig, build_planar_fhnn, planar_arguments
from fhnn.training.planar_tracks import (
    PlanarTrackConfig,
    fit_planar_tracks,
    make_windows,
    noise_scales,
    observed_pose,
    pose_residuals,
    window_size,
)


@pytest.fixture(scope="module")
def data():
    return simulate_planar("turning_vortex", n_traj=10, duration=3.0, test_duration=3.0, dt=0.1, seed=2)


def test_windows_cover_each_trajectory_to_its_last_sample(data) -> None:
    train = data.splits["train"]
    size = window_size(train, 1.0)
    assert size == 11  # 1 s at 0.1 s: 10 intervals
    w = make_windows(train, size, observed_pose(data, train))
    # 31 samples: windows start at 0, 10 and 20, the last ending at the last sample
    assert w.t.shape == (3 * train.t.shape[0], 11)
    np.testing.assert_array_equal(w.t[2], train.t[0, 20:31])
    np.testing.assert_array_equal(w.pose[1], train.states[0, 10:21, :3])  # a simulation's observations
    np.testing.assert_array_equal(w.start[4], train.states[1, 10])
    # 2.5 s windows on 3 s trajectories: one from the start, one ending at the last sample
    w = make_windows(train, window_size(train, 2.5), observed_pose(data, train))
    np.testing.assert_array_equal(w.t[1], train.t[0, 5:31])
    with pytest.raises(ConfigError, match="no trajectory holds a window of 40 samples"):
        make_windows(train, 40, observed_pose(data, train))


def test_the_true_equations_leave_only_rk4_s_error_in_the_pose(data) -> None:
    train = data.splits["train"]  # noise-free: the observations are the truth
    w = make_windows(train, window_size(train, 3.0), observed_pose(data, train))
    eom = data.truth().equations()
    coarse, fine = (pose_residuals(eom, w.start, w, (1.0, 1.0), n) for n in (1, 4))
    assert float(jnp.max(jnp.abs(fine))) < 1e-7
    assert float(jnp.max(jnp.abs(coarse))) > 20 * float(jnp.max(jnp.abs(fine)))  # RK4: 4⁴ = 256 smaller
    # a start 1 cm off in x is a residual of exactly one noise unit at the window's first sample
    off = pose_residuals(eom, w.start.at[:, 0].add(0.01), w, (0.01, 1.0), 4)
    np.testing.assert_allclose(np.asarray(off[:, 0, 0]), 1.0, rtol=1e-9)


def test_the_fit_lowers_its_objective_and_the_guard_keeps_the_better_model() -> None:
    data = simulate_planar(
        "turning_vortex", n_traj=10, duration=3.0, test_duration=3.0, dt=0.1, seed=2, obs_noise=1e-3
    )
    assert noise_scales(data) == (1e-3, 1e-3)
    # a fresh model: its added masses at half the body's, its damping and flow nets untrained
    model = build_planar_fhnn(
        PlanarModelConfig(width=8, depth=2), **planar_arguments(data), key=jax.random.PRNGKey(0)
    )
    tracks = fit_planar_tracks(model, data, PlanarTrackConfig(window=1.0, steps=60, substeps=1))
    # from 784 to 5.7 noise variances per residual in a smoke run (1 is the noise floor)
    assert len(tracks.history) == 60 and tracks.history[-1] < 0.05 * tracks.history[0], tracks.history
    kept_mass = np.asarray(tracks.model.mass_raw)
    if tracks.kept:
        assert tracks.val_after < tracks.val_before and not np.array_equal(kept_mass, model.mass_raw)
    else:
        np.testing.assert_array_equal(kept_mass, np.asarray(model.mass_raw))
    assert tracks.kept and tracks.val_after < 0.5 * tracks.val_before  # smoke run: 432 -> 45
    with pytest.raises(ConfigError, match="window"):
        PlanarTrackConfig(window=0.0)
