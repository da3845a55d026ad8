"""The ground-truth simulator: exact solutions, energy, consistency, reproducibility."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fhnn.data.simulate import SimulationConfig, integrate, simulate_dataset
from fhnn.errors import ConfigError
from fhnn.physics.actuation import no_actuation
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.scenarios import get_scenario

from .conftest import small_dataset
from .reference import reference_actuation, reference_vector_field

STILL = dict(gamma=0.0, m_ax=12.0, m_ay=20.0, c_l=3.0)


def test_damped_body_in_still_water_matches_exact_solution(rng):
    # linear drag only: v_i(t) = v0_i exp(-c_l t / (M + m_a,i)), x_i = x0_i + v0_i τ_i (1 - exp(-t/τ_i))
    sc = get_scenario("steady_vortex", **STILL, cq_inf=0.0, cq_0=0.0)
    eom = EquationsOfMotion.of(sc.flow(), sc.body())
    y0 = sc.sample_initial_states(rng, 8)
    ts = np.linspace(0.0, 20.0, 401)
    states, ok = integrate(eom, y0, no_actuation(8), ts)
    assert ok.all()
    tau = (10.0 + np.array([12.0, 20.0])) / 3.0
    decay = np.exp(-ts[None, :, None] / tau)
    v = y0[:, None, 2:] * decay
    x = y0[:, None, :2] + y0[:, None, 2:] * tau * (1 - decay)
    err = np.abs(states - np.concatenate([x, v], axis=-1)).max()
    assert err < 1e-10, err


def test_kinetic_energy_never_increases_without_actuation_in_still_water(rng):
    sc = get_scenario("steady_vortex", **STILL, v0_std=1.0)  # quadratic + linear drag
    eom = EquationsOfMotion.of(sc.flow(), sc.body())
    y0 = sc.sample_initial_states(rng, 16)
    states, ok = integrate(eom, y0, no_actuation(16), np.linspace(0.0, 30.0, 601))
    assert ok.all()
    energy = 0.5 * (22.0 * states[..., 2] ** 2 + 30.0 * states[..., 3] ** 2)
    increase = np.diff(energy, axis=1).max()
    assert increase <= 1e-15, increase
    assert energy[:, -1].max() < 0.05 * energy[:, 0].min()  # and it really dissipates


def test_derivs_equal_the_equations_of_motion_at_clean_states(scenario_dataset):
    # checked against the independent NumPy implementation of the physics
    f = reference_vector_field(scenario_dataset.scenario_object())
    for split in scenario_dataset.splits.values():
        for i in range(split.n_traj):
            for j in range(0, split.n_times, 7):
                force = reference_actuation(split.actuation[i], split.t[j])
                np.testing.assert_allclose(split.forces[i, j], force, atol=1e-14)
                expected = f(split.t[j], split.states_clean[i, j], force)
                np.testing.assert_allclose(split.derivs[i, j], expected, rtol=1e-12, atol=1e-14)


def test_reintegrating_a_stored_trajectory_reproduces_it(scenario_dataset):
    # an independent integrator (scipy DOP853, tighter tolerance, NumPy physics) from the first state
    f = reference_vector_field(scenario_dataset.scenario_object())
    split = scenario_dataset.test
    for i in range(min(2, split.n_traj)):
        act = split.actuation[i]
        sol = solve_ivp(
            lambda t, s, act=act: f(t, s, reference_actuation(act, t)),
            (split.t[0], split.t[-1]),
            split.states_clean[i, 0],
            method="DOP853",
            rtol=1e-13,
            atol=1e-13,
            t_eval=split.t,
        )
        assert sol.success
        err = np.abs(sol.y.T - split.states_clean[i]).max()
        assert err < 1e-8, (scenario_dataset.scenario, err)


def test_same_seed_same_contents_other_seed_differs():
    a, b = small_dataset("noisy_flow", seed=7), small_dataset("noisy_flow", seed=7)
    c = small_dataset("noisy_flow", seed=8)
    assert a.scenario_params == b.scenario_params
    for name in a.splits:
        for key, array in a[name].arrays().items():
            np.testing.assert_array_equal(array, b[name].arrays()[key])
    assert a.scenario_params["modes"] != c.scenario_params["modes"]
    assert not np.array_equal(a.train.states, c.train.states)


def test_splits_are_disjoint_and_sized(scenario_dataset):
    starts = np.concatenate([s.states_clean[:, 0] for s in scenario_dataset.splits.values()])
    assert len(np.unique(starts.round(12), axis=0)) == len(starts)
    config = SimulationConfig.from_dict(scenario_dataset.extra["simulation"])
    assert {k: v.n_traj for k, v in scenario_dataset.splits.items()} == config.split_sizes()


def test_observation_noise_on_states_only(rng):
    ds = small_dataset("noisy_flow", n_traj=20)
    noise = ds.train.states - ds.train.states_clean
    assert ds.obs_noise == 1e-3
    assert abs(noise.std() / 1e-3 - 1) < 0.05
    assert abs(noise.mean()) < 1e-4
    clean = small_dataset("steady_vortex", obs_noise=0.0)
    np.testing.assert_array_equal(clean.train.states, clean.train.states_clean)
    assert not np.shares_memory(clean.train.states, clean.train.states_clean)


def test_obstacle_redraws_close_approaches_and_counts_them():
    ds = small_dataset("obstacle", n_traj=20, duration=20.0, test_duration=20.0)
    for split in ds.splits.values():
        r = np.hypot(split.states_clean[..., 0], split.states_clean[..., 1])
        assert r.min() >= 1.1 * 0.5
    assert sum(ds.extra["redraws"].values()) > 0  # with 20 s trajectories some bodies hit the cylinder


def test_initial_state_distributions(rng):
    y0 = get_scenario("steady_vortex").sample_initial_states(rng, 4000)
    r = np.hypot(y0[:, 0], y0[:, 1])
    assert 0.5 <= r.min() and r.max() <= 3.0
    assert abs(y0[:, 2:].std() - 0.2) < 0.01
    wave = get_scenario("wave")
    y0 = wave.sample_initial_states(rng, 4000)
    u0 = np.stack([np.asarray(wave.flow().velocity(jnp.asarray(p), 0.0)) for p in y0[:200, :2]])
    assert abs((y0[:200, 2:] - u0).std() - 0.05) < 0.01
    assert (y0[:, 1] <= -1).all() and (y0[:, 1] >= -3).all()


def test_split_sizes_and_bad_settings():
    assert SimulationConfig(n_traj=100).split_sizes() == {"train": 70, "val": 20, "test": 10}
    sb = get_scenario("solid_body_vortex")
    cfg = SimulationConfig.for_scenario(sb)
    assert (cfg.n_traj, cfg.duration, cfg.dt, cfg.actuation) == (64, 8.0, 0.02, "none")
    assert cfg.split_sizes() == {"train": 45, "val": 6, "test": 13}
    with pytest.raises(ConfigError, match="n_traj must be >= 1, got 0"):
        SimulationConfig(n_traj=0)
    with pytest.raises(ConfigError, match="n_traj = 2 is too small"):
        SimulationConfig(n_traj=2)
    with pytest.raises(ConfigError, match="dt must be > 0, got 0.0"):
        SimulationConfig(dt=0.0)
    with pytest.raises(ConfigError, match="split fractions must be >= 0 and sum to 1"):
        SimulationConfig(split=(0.5, 0.2, 0.2))
    with pytest.raises(ConfigError, match="duration .* is shorter than dt"):
        SimulationConfig(duration=0.01, dt=0.05)


def test_simulator_failures_are_redrawn_or_reported():
    # an obstacle whose bodies all start inside the exclusion zone can never be accepted
    sc = get_scenario("obstacle", x0_min=-0.3, x0_max=-0.2, y0_min=-0.1, y0_max=0.1, v0_std=0.0)
    cfg = SimulationConfig.for_scenario(sc, n_traj=3, duration=1.0, test_duration=1.0, max_redraw_rounds=2)
    with pytest.raises(Exception, match=r"still rejected or failed after 2 rounds"):
        simulate_dataset(sc, cfg)
