"""The 3-DOF equations (docs/spec.md §7) against exact cases: energy, the Munk instability, the
2-DOF body, a body turning with the water, dissipation."""

import math
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fhnn.physics.body import CoefficientLaws, Constant, ReynoldsDrag
from fhnn.physics.dynamics import EquationsOfMotion
from fhnn.physics.flows import LambOseenVortex, SolidBodyRotation, StillWater
from fhnn.physics.integrators import adaptive_solve
from fhnn.physics.planar import (
    DiagonalDamping,
    PlanarEquations,
    munk_growth_rate,
    rotation,
    water_at_body,
)

DRAG = ReynoldsDrag(c_inf=0.6, c_0=0.4, sigma_ref=0.2)
NO_DAMPING = DiagonalDamping(
    linear=(0.0, 0.0, 0.0), areas=(0.0, 0.0), quadratic=Constant(0.0), yaw_quadratic=0.0
)


def body(flow, damping=NO_DAMPING, added=(1.5, 9.0, 0.6), x_g=0.0, m_26=0.0):
    return PlanarEquations(
        flow=flow, damping=damping, mass=10.0, inertia=1.0, added_mass=jnp.array(added), x_g=x_g, m_26=m_26
    )


@pytest.mark.parametrize(("x_g", "m_26"), [(0.0, 0.0), (0.2, 0.4)])
def test_kinetic_energy_is_conserved_in_still_water_without_damping(x_g, m_26) -> None:
    eom = body(StillWater(), x_g=x_g, m_26=m_26)
    s0 = jnp.array([0.3, -0.2, 0.4, 0.5, -0.3, 0.8])
    ts = jnp.linspace(0.0, 20.0, 201)
    states, ok = adaptive_solve(lambda s, t: eom(s, t, jnp.zeros(3)), s0, ts, rtol=1e-12, atol=1e-12)
    energy = jax.vmap(eom.kinetic_energy)(states)
    assert bool(ok)
    assert float(jnp.max(jnp.abs(energy / energy[0] - 1.0))) < 1e-9
    # the motion is not trivial: the heading turns and the velocity changes direction
    assert float(jnp.ptp(states[:, 2])) > 1.0 and float(jnp.ptp(states[:, 4])) > 0.1


def test_the_munk_instability_grows_at_its_linearised_rate() -> None:
    eom = body(StillWater())
    speed = 0.7
    rate = munk_growth_rate(10.0, 1.0, (1.5, 9.0, 0.6), speed)
    straight = jnp.array([0.0, 0.0, 0.0, speed, 0.0, 0.0])
    jac = jax.jacfwd(lambda s: eom(s, 0.0, jnp.zeros(3)))(straight)
    eigen = np.linalg.eigvals(np.asarray(jac[4:, 4:]))  # sway and yaw rate
    assert max(eigen.real) == pytest.approx(rate, rel=1e-12)
    # and the nonlinear solution: a tiny yaw rate grows by e^{λt} before it saturates
    s0 = straight.at[5].set(1e-12)  # after 8/λ, 3e-9: still linear; the decaying mode gone
    ts = jnp.linspace(0.0, 8.0 / rate, 41)
    states, ok = adaptive_solve(lambda s, t: eom(s, t, jnp.zeros(3)), s0, ts, rtol=1e-12, atol=1e-15)
    growth = math.log(abs(float(states[-1, 5])) / abs(float(states[-11, 5]))) / float(ts[-1] - ts[-11])
    assert bool(ok) and growth == pytest.approx(rate, rel=1e-4)
    with pytest.raises(ValueError, match="no Munk instability"):
        munk_growth_rate(10.0, 1.0, (9.0, 1.5, 0.6), speed)


def test_an_axisymmetric_body_follows_the_2dof_path_whatever_its_heading_does() -> None:
    """m_11 = m_22, the 2-DOF drag law on both translational axes, x_G = 0: (x, y) is §1's path
    under the same world-frame forces, while the body turns."""
    flow = LambOseenVortex(gamma=5.0, core_radius=1.0, modulation=0.3, period=20.0)
    damping = DiagonalDamping(linear=(3.0, 3.0, 0.4), areas=(0.02, 0.02), quadratic=DRAG, yaw_quadratic=0.2)
    planar = body(flow, damping, added=(12.0, 12.0, 0.6))
    point = EquationsOfMotion(
        flow=flow,
        coefficients=CoefficientLaws(Constant(12.0), Constant(12.0), DRAG, Constant(3.0)),
        mass=10.0,
        rho=1000.0,
        area=0.02,
    )

    def world_force(t):
        return jnp.stack([0.8 * jnp.sin(0.9 * t), 0.5 * jnp.cos(1.7 * t + 0.3)])

    def planar_field(s, t):
        tau_xy = rotation(s[2]).T @ world_force(t)
        return planar(s, t, jnp.concatenate([tau_xy, jnp.array([0.3 * jnp.sin(2.1 * t)])]))

    xy0, v0, psi0 = jnp.array([1.2, -0.4]), jnp.array([0.1, 0.25]), 0.7
    s0 = jnp.concatenate([xy0, jnp.array([psi0]), rotation(psi0).T @ v0, jnp.array([0.5])])
    ts = jnp.linspace(0.0, 15.0, 301)
    turning, ok1 = adaptive_solve(planar_field, s0, ts, rtol=1e-12, atol=1e-12)
    path, ok2 = adaptive_solve(
        lambda s, t: point(s, t, world_force(t)), jnp.concatenate([xy0, v0]), ts, rtol=1e-12, atol=1e-12
    )
    assert bool(ok1) and bool(ok2)
    assert float(jnp.ptp(turning[:, 2])) > 0.5  # it turns
    assert float(jnp.max(jnp.abs(turning[:, :2] - path[:, :2]))) < 1e-8
    world_velocity = jax.vmap(lambda s: rotation(s[2]) @ s[3:5])(turning)
    assert float(jnp.max(jnp.abs(world_velocity - path[:, 2:]))) < 1e-8


def test_a_body_turning_with_the_water_feels_no_damping() -> None:
    """At the centre of a solid-body rotation Ω the water turns at ω/2 = Ω: a body spinning at Ω
    keeps spinning, however strong its yaw damping."""
    omega = 0.8
    damping = DiagonalDamping(linear=(3.0, 3.0, 2.0), areas=(0.02, 0.05), quadratic=DRAG, yaw_quadratic=1.0)
    eom = body(SolidBodyRotation(omega=omega), damping)
    assert np.allclose(water_at_body(eom.flow, jnp.array([0.0, 0.0, 0.3]), 0.0), [0.0, 0.0, omega])
    rates = eom(jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, omega]), 0.0, jnp.zeros(3))
    assert np.allclose(rates, [0.0, 0.0, omega, 0.0, 0.0, 0.0], atol=1e-15)
    braked = eom(jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 2 * omega]), 0.0, jnp.zeros(3))
    assert float(braked[5]) < 0.0


def test_the_simulator_damping_dissipates(rng) -> None:
    damping = DiagonalDamping(linear=(3.0, 6.0, 0.5), areas=(0.01, 0.05), quadratic=DRAG, yaw_quadratic=0.3)
    nus = jnp.asarray(rng.normal(0.0, 1.0, (500, 3)))
    power = jax.vmap(lambda nu: nu @ damping(nu))(nus)
    assert float(jnp.min(power)) > 0.0


# --- the learned model, the data set -------------------------------------------------------------


@pytest.fixture(scope="module")
def small_planar():
    from fhnn.data.planar import simulate_planar

    return simulate_planar("turning_time_varying_vortex", n_traj=6, duration=2.0, test_duration=3.0, seed=5)


def _model(dataset, seed=0, **settings):
    from fhnn.models.planar import PlanarModelConfig, build_planar_fhnn, planar_arguments

    return build_planar_fhnn(
        PlanarModelConfig(width=8, depth=2, time_modes=2, **settings),
        **planar_arguments(dataset),
        key=jax.random.PRNGKey(seed),
    )


def _perturbed(model, seed):
    import equinox as eqx

    leaves, treedef = jax.tree_util.tree_flatten(eqx.filter(model, eqx.is_inexact_array))
    keys = jax.random.split(jax.random.PRNGKey(seed), len(leaves))
    noisy = [x + 0.3 * jax.random.normal(k, x.shape) for x, k in zip(leaves, keys, strict=True)]
    return eqx.combine(jax.tree_util.tree_unflatten(treedef, noisy), model)


def test_the_learned_field_matches_central_differences(small_planar) -> None:
    model = _perturbed(_model(small_planar), 1)
    s = jnp.array([0.9, -0.6, 0.4, 0.3, -0.1, 0.2])
    tau = jnp.array([0.2, -0.1, 0.05])
    jac = np.asarray(jax.jacfwd(lambda x: model(x, 1.3, tau))(s))
    h = 1e-6
    for j in range(6):
        e = jnp.zeros(6).at[j].set(h)
        fd = (np.asarray(model(s + e, 1.3, tau)) - np.asarray(model(s - e, 1.3, tau))) / (2 * h)
        np.testing.assert_allclose(jac[:, j], fd, rtol=1e-6, atol=1e-8)
    # and in the force: the field is affine in τ with slope (M_RB + M_A)⁻¹
    d_tau = np.asarray(jax.jacfwd(lambda f: model(s, 1.3, f))(tau))[3:]
    np.testing.assert_allclose(d_tau, np.linalg.inv(np.asarray(model.equations().mass_matrix())), rtol=1e-12)


@pytest.mark.parametrize(
    "settings", [{}, {"damping": "full"}, {"damping": "full", "damping_inputs": "velocity"}]
)
def test_the_learned_damping_dissipates_for_any_weights(small_planar, rng, settings) -> None:
    nus = jnp.asarray(rng.normal(0.0, 1.0, (400, 3)))
    for seed in range(5):
        model = _perturbed(_model(small_planar, seed, **settings), seed + 10)
        power = jax.vmap(lambda nu: nu @ model.damping(nu))(nus)
        assert float(jnp.min(power)) >= -1e-12 * float(jnp.max(power))
        assert float(jnp.min(model.added_mass())) > 0.0
        matrix = np.asarray(model.damping.matrix(nus[0]))
        off = matrix - np.diag(np.diag(matrix))
        if settings:  # the full matrix couples the axes, with a skew part that does no work
            coupled = off[~np.eye(3, dtype=bool)]
            assert np.min(np.abs(coupled)) > 0
            assert np.max(np.abs(off - off.T)) > 1e-3 * np.max(np.abs(off))
        else:
            assert np.all(off == 0.0)


def test_a_planar_data_set_survives_its_file_and_a_wrong_file_is_refused(small_planar, tmp_path) -> None:
    from fhnn.data.planar import read_planar, write_planar
    from fhnn.errors import DataFormatError

    path = write_planar(small_planar, tmp_path / "turning.h5")
    back = read_planar(path)
    assert back.params == small_planar.params and back.mass == small_planar.mass
    for name, split in small_planar.splits.items():
        for field in ("t", "states", "states_clean", "forces", "thrust"):
            np.testing.assert_array_equal(getattr(back.splits[name], field), getattr(split, field))
    # the recorded forces are the thrusters' sinusoids at the samples
    from fhnn.physics.actuation import actuation_force

    train = small_planar.splits["train"]
    assert np.allclose(
        train.forces[0, 7], actuation_force(jnp.asarray(train.thrust[0]), train.t[0, 7]), atol=1e-15
    )
    import h5py

    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.attrs["kind"] = "point"
    with pytest.raises(DataFormatError, match="not a turning body's data set"):
        read_planar(tmp_path / "other.h5")
    with pytest.raises(DataFormatError, match="no such file"):
        read_planar(tmp_path / "missing.h5")


def test_bad_planar_settings_are_refused_by_name() -> None:
    from fhnn.data.planar import simulate_planar
    from fhnn.errors import ConfigError
    from fhnn.physics.planar_scenarios import get_planar_scenario

    with pytest.raises(ConfigError, match="unknown turning scenario 'vortex'"):
        get_planar_scenario("vortex")
    with pytest.raises(ConfigError, match="added_mass must be 3 finite numbers"):
        get_planar_scenario("turning_vortex", added_mass=(1.0, -2.0, 0.5))
    with pytest.raises(ConfigError, match="unknown parameter"):
        get_planar_scenario("turning_vortex", gama=4.0)
    with pytest.raises(ConfigError, match="n_traj"):
        simulate_planar(n_traj=2)


def test_inspect_reads_the_damping_over_the_velocities_the_data_cover(small_planar) -> None:
    """With the true flow in the model, the covered relative velocities are the simulation's own
    (:func:`fhnn.evaluation.planar.relative_velocities`, to the bit); the diagonal damping's
    force is its coefficient times the velocity; the masses' and the damping's errors are the
    truth's, computed here again."""
    import equinox as eqx

    from fhnn.api.planar_inspect import inspect_turning
    from fhnn.evaluation.planar import relative_velocities

    model = _perturbed(_model(small_planar), 3)
    with_truth = eqx.tree_at(lambda m: m.flow, model, small_planar.truth().flow())
    found = inspect_turning(with_truth, small_planar, max_points=100)
    assert found.files == () and len(found.damping) == 100
    d = found.damping
    np.testing.assert_array_equal(d[["u_r", "v_r", "r_r"]].to_numpy(), relative_velocities(small_planar, 100))
    for speed, force, coef in (("u_r", "X_d", "d_11"), ("v_r", "Y_d", "d_22"), ("r_r", "N_d", "d_66")):
        np.testing.assert_allclose(d[force], d[coef] * d[speed], rtol=1e-12, atol=1e-15)
        assert (d[coef] > 0).all()
        row = found.coefficients.set_index("name").loc[coef]
        assert (row["low"], row["high"]) == (d[coef].min(), d[coef].max())
        err = np.linalg.norm(d[force] - d[f"true_{force}"]) / np.linalg.norm(d[f"true_{force}"])
        assert row["rel_error"] == pytest.approx(err, rel=1e-12)
    true = jax.vmap(small_planar.truth().damping())(jnp.asarray(d[["u_r", "v_r", "r_r"]].to_numpy()))
    np.testing.assert_allclose(
        d[["true_X_d", "true_Y_d", "true_N_d"]].to_numpy(), np.asarray(true), rtol=1e-12
    )
    masses = found.coefficients.set_index("name").loc[["m_11", "m_22", "m_66"]]
    np.testing.assert_array_equal(masses["value"], np.asarray(model.added_mass()))
    np.testing.assert_array_equal(masses["true"], small_planar.params["added_mass"])


def test_the_turning_commands_simulate_train_and_evaluate_and_refuse_bad_input(tmp_path, capsys) -> None:
    """``fhnn turning``: a short run end to end, the report's numbers as the library computes
    them, and one-line errors with status 2 (no file left behind)."""
    import json

    from fhnn.api.planar import evaluate_turning, load_turning
    from fhnn.cli.app import main

    def run(argv):
        with pytest.raises(SystemExit) as info:
            main(argv)
        out = capsys.readouterr()
        return info.value.code, out.out, out.err

    data, folder = tmp_path / "t.h5", tmp_path / "run"
    sim = ["turning", "simulate", "turning_vortex", "-o", str(data), "--n-traj", "6", "--duration", "1"]
    assert run([*sim, "--test-duration", "2", "--seed", "4", "-q"])[0] == 0
    code, out, _ = run(
        ["turning", "train", str(data), "-o", str(folder), "--adam-steps", "10", "--lbfgs-steps", "0", "-q"]
    )
    assert code == 0 and "validation loss" in out and (folder / "model.eqx").is_file()
    code, out, _ = run(
        [
            "turning",
            "evaluate",
            str(folder),
            str(data),
            "--horizon",
            "2",
            "--json",
            "--figure",
            str(tmp_path / "f.png"),
        ]
    )
    assert code == 0
    report = json.loads(out)
    again = evaluate_turning(load_turning(folder), data, horizon=2.0)
    assert report["forecast"]["rmse_pos"] == pytest.approx(again["forecast"]["rmse_pos"], rel=1e-12)
    assert report["added_mass"]["m_22"]["true"] == 9.0
    code, out, _ = run(["info", str(data)])
    assert (
        code == 0 and "a turning body's data set under known forces; scenario turning_vortex, seed 4" in out
    )
    # fhnn.info, what the command prints, takes a turning body's file or data set as well
    import fhnn
    from fhnn.api.planar_info import turning_info
    from fhnn.data.planar import read_planar as read_turning

    code, out, _ = run(["info", str(data), "--json"])
    described = fhnn.info(data)
    assert code == 0 and json.loads(out) == json.loads(json.dumps(described))
    assert described == turning_info(data) == fhnn.info(read_turning(data))
    assert described["splits"]["train"]["trajectories"] == 4 and described["mass"] == 10.0
    code, out, err = run(["turning", "inspect", str(folder), str(data), "--max-points", "50"])
    assert code == 0, err
    said = " ".join(out.split())
    assert "m_22" in said and "d_66 over r_r" in said
    for name in ("coefficients.csv", "damping.csv", "damping.png"):
        assert (folder / name).stat().st_size > 0
    # predict: with --fit-window 0 each track continued from its estimated last state (noise-free
    # table: the truth's), as predict_turning continues it
    import pandas as pd

    from fhnn.api.planar_forecast import forecast_turning
    from fhnn.api.planar_predict import COLUMNS, predict_turning
    from fhnn.data.planar import read_planar
    from fhnn.data.planar_table import observed_table

    simulated = read_planar(data)
    history = pd.DataFrame(observed_table(simulated))
    history.to_csv(tmp_path / "h.csv", index=False)
    forecast_path = tmp_path / "forecast.csv"
    predict = [
        "turning",
        "predict",
        str(folder),
        "--history",
        str(tmp_path / "h.csv"),
        "-o",
        str(forecast_path),
    ]
    code, _, err = run([*predict, "--duration", "1", "--dt", "0.25", "--fit-window", "0"])
    assert code == 0, err
    forecast = pd.read_csv(forecast_path)
    plain = predict_turning(folder, tmp_path / "h.csv", 1.0, dt=0.25)
    np.testing.assert_allclose(forecast[list(COLUMNS[1:])], plain[list(COLUMNS[1:])], rtol=1e-12, atol=1e-12)
    assert (
        tuple(forecast.columns) == COLUMNS and forecast["traj_id"].nunique() == history["traj_id"].nunique()
    )
    assert (forecast.groupby("traj_id").size() == 5).all()  # 0, 0.25, ..., 1 s after the last sample
    first = forecast.groupby("traj_id").head(1).set_index("traj_id")
    for track, row in first.iterrows():
        split, index = track.split("-")
        part = simulated.splits[split]
        end = part.states_clean[int(index), part.lengths[int(index)] - 1]
        assert row["t"] == pytest.approx(part.t[int(index), part.lengths[int(index)] - 1], abs=1e-12)
        np.testing.assert_allclose(row[["x", "y", "heading"]].to_numpy(float), end[:3], atol=1e-4)
        np.testing.assert_allclose(row[["u", "v", "r"]].to_numpy(float), end[3:], atol=2e-2)
    # by default the start is fitted to the last 10 s (here whole tracks): the model's rollout
    # from the fitted state ends nearer the observed last pose than the smoothed estimate's misfit
    fitted = forecast_turning(folder, tmp_path / "h.csv", 1.0, dt=0.25)
    assert tuple(fitted.columns) == COLUMNS and len(fitted) == len(forecast)
    assert np.all(np.isfinite(fitted[list(COLUMNS[2:])].to_numpy()))
    assert not np.allclose(fitted[["u", "v", "r"]], forecast[["u", "v", "r"]], rtol=0, atol=1e-9)
    # four samples a track give no noise estimate (it needs five): the fit runs at the floor
    short = history.groupby("traj_id").tail(4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        brief = forecast_turning(folder, short, 1.0, dt=0.25)
    assert not [w for w in caught if "diverged" in str(w.message)]  # no track fell back
    assert brief["traj_id"].nunique() == history["traj_id"].nunique()
    assert (brief.groupby("traj_id").size() == 5).all()
    assert np.all(np.isfinite(brief[list(COLUMNS[2:])].to_numpy()))
    # the last track keeps one sample: no state can be estimated from it
    single = history[history["traj_id"] != history["traj_id"].iloc[-1]]
    single = pd.concat([single, history[history["traj_id"] == history["traj_id"].iloc[-1]].head(1)])
    single.to_csv(tmp_path / "h1.csv", index=False)
    one = [*predict[:4], str(tmp_path / "h1.csv"), "-o", str(tmp_path / "r2.csv"), "--duration", "1"]
    bad = [
        (["turning", "evaluate", str(folder), str(data), "--horizon", "3"], "exceeds the shortest test"),
        (
            ["turning", "evaluate", str(folder), str(data), "--horizon", "1.5"],
            "horizon must be a positive whole number",
        ),
        (["turning", "train", str(data), "-o", str(folder)], "holds a model already"),
        (["turning", "train", str(tmp_path / "none.h5"), "-o", str(tmp_path / "r2")], "no such file"),
        (["turning", "evaluate", str(tmp_path), str(data)], "no such file"),
        (["turning", "inspect", str(folder), str(data), "--out", str(tmp_path / "r2")], "does not exist"),
        ([*predict, "--duration", "0"], "duration must be a positive number of seconds"),
        ([*predict, "--duration", "1", "--fit-window", "-1"], "fit_window must be zero or a positive"),
        ([*predict[:-1], str(tmp_path / "r2.txt"), "--duration", "1"], "give a .csv or .parquet file"),
        (one, "has 1 sample(s)"),
        (
            ["turning", "inspect", str(folder), str(data), "--max-points", "0"],
            "max_points must be at least 1",
        ),
        (["turning", "simulate", "turning_vortex", "-o", str(tmp_path / "x.h5"), "--dt", "0"], "dt"),
    ]
    for argv, message in bad:
        code, out, err = run(argv)
        assert code == 2 and out == "", argv
        assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "r2").exists()
    assert not (tmp_path / "r2.csv").exists() and not (tmp_path / "r2.txt").exists()


# --- a turning body's table ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def fine_planar():
    """Noise-free trajectories sampled every 0.01 s, for tables at irregular times."""
    from fhnn.data.planar import simulate_planar

    return simulate_planar("turning_vortex", n_traj=6, duration=6.0, test_duration=6.0, dt=0.01, seed=2)


def _truth_at(imported, source, split="train"):
    """The imported split's states and the simulation's truth at the same samples, stacked."""
    part = imported.splits[split]
    got, want = [], []
    for k, traj_id in enumerate(imported.params["ids"][split]):
        name, i = traj_id.split("-")
        n = part.lengths[k]
        rows = np.rint(part.t[k, :n] / 0.01).astype(int)
        got.append(part.states[k, :n])
        want.append(source.splits[name].states_clean[int(i), rows])
    return np.concatenate(got), np.concatenate(want)


def test_a_noisy_irregular_table_gives_the_body_frame_velocities(fine_planar) -> None:
    """Positions with 1 mm and heading with 3 mrad noise every 0.03–0.07 s: the noise levels
    are found, and the smoothed pose and body-frame velocity lie within a few noise levels of
    the truth (the velocity error far below the noise over the step, 1 mm / 0.05 s = 2 cm/s)."""
    from fhnn.api.planar import import_turning
    from fhnn.data.planar_table import observed_table

    columns = observed_table(fine_planar, position_noise=1e-3, heading_noise=3e-3, steps=(3, 7), seed=0)
    data = import_turning(columns_frame(columns), mass=10.0, inertia=1.0, seed=1)
    assert data.params["noise"]["position"] == pytest.approx(1e-3, rel=0.15)
    assert data.params["noise"]["heading"] == pytest.approx(3e-3, rel=0.15)
    got, want = _truth_at(data, fine_planar)
    rms = np.sqrt(np.mean((got - want) ** 2, axis=0))
    assert np.all(rms[:2] < 1e-3) and rms[2] < 3e-3  # the smoothed pose is nearer than the noise
    assert np.all(rms[3:5] < 5e-3) and rms[5] < 1.5e-2  # u, v [m/s]; r [rad/s]
    # the reference states are the observations themselves
    part = data.splits["train"]
    assert np.ptp(part.states_clean[0, : part.lengths[0], 0] - part.states[0, : part.lengths[0], 0]) > 1e-3


def columns_frame(columns):
    import pandas as pd

    return pd.DataFrame(columns)


def test_world_frame_forces_are_turned_into_the_body_frame(fine_planar) -> None:
    """``Fx, Fy`` = R(ψ) (Fu, Fv) on a noise-free table import as the body-frame ``Fu, Fv`` (and
    a zero moment); the pose comes back to 1e-6, the velocities to 1e-4."""
    from fhnn.api.planar import import_turning
    from fhnn.data.planar_table import observed_table

    body = observed_table(fine_planar, steps=(2, 4), seed=3)
    c, s = np.cos(body["heading"]), np.sin(body["heading"])
    world = {k: v for k, v in body.items() if k not in ("Fu", "Fv", "Mz")}
    world["Fx"] = c * body["Fu"] - s * body["Fv"]
    world["Fy"] = s * body["Fu"] + c * body["Fv"]
    a = import_turning(columns_frame(body), mass=10.0, inertia=1.0)
    b = import_turning(columns_frame(world), mass=10.0, inertia=1.0)
    for name in ("train", "val", "test"):
        sa, sb = a.splits[name], b.splits[name]
        np.testing.assert_allclose(sb.forces[..., :2], sa.forces[..., :2], atol=1e-6)
        assert np.all(sb.forces[..., 2] == 0.0)
    got, want = _truth_at(a, fine_planar)
    assert np.max(np.abs(got[:, :3] - want[:, :3])) < 1e-6  # the noise estimate: ~1e-7 of cubic misfit
    assert np.max(np.abs(got[:, 3:] - want[:, 3:])) < 1e-4


def test_training_on_a_table_sees_its_forces_between_samples(fine_planar) -> None:
    """The one-step loss of the true equations on an imported noise-free table is the RK4 error
    of a linearly read force, small; with the forces dropped it is large."""
    import dataclasses

    from fhnn.api.planar import import_turning
    from fhnn.data.planar_table import observed_table
    from fhnn.training.planar import _pairs, rate_scales, step_residuals

    columns = observed_table(fine_planar, steps=(3, 5), seed=4)
    data = import_turning(columns_frame(columns), mass=10.0, inertia=1.0)
    train = data.splits["train"]
    eom = fine_planar.truth().equations()
    scales = rate_scales(train)
    with_forces = float(jnp.sqrt(jnp.mean(step_residuals(eom, _pairs(train), scales, 4) ** 2)))
    unforced = dataclasses.replace(train, forces=np.zeros_like(train.forces))
    without = float(jnp.sqrt(jnp.mean(step_residuals(eom, _pairs(unforced), scales, 4) ** 2)))
    assert with_forces < 2e-3 and without > 20 * with_forces


def test_bad_turning_tables_are_refused_in_one_line(fine_planar, tmp_path, capsys) -> None:
    from fhnn.cli.app import main
    from fhnn.data.planar_table import observed_table
    from fhnn.data.table import write_table

    good = observed_table(fine_planar, steps=(4, 6), seed=5)

    def table(name, drop=(), **extra):
        cols = {k: v for k, v in good.items() if k not in drop} | extra
        return str(write_table(cols, tmp_path / f"{name}.csv"))

    out = str(tmp_path / "out.h5")
    base = ["import", "-o", out, "--mass", "10"]
    bad = [
        ([*base, table("nopos", drop=("x",)), "--inertia", "1"], "missing column(s) x"),
        ([*base, table("fu", drop=("Fv",)), "--inertia", "1"], "column 'Fv' is missing"),
        ([*base, table("mz", drop=("Fu", "Fv")), "--inertia", "1"], "'Mz' needs the body-frame forces"),
        ([*base, table("both", Fx=good["Fu"], Fy=good["Fv"]), "--inertia", "1"], "in one frame"),
        ([*base, table("rudder", rudder=good["Fu"]), "--inertia", "1"], "unknown column(s) rudder"),
        ([*base, table("good")], "--inertia is needed"),
        ([*base, table("good"), "--inertia", "-1"], "--inertia must be a positive number"),
        ([*base, table("good"), "--inertia", "1", "--area", "0.1"], "--area and --forcing apply"),
        ([*base, table("point", drop=("heading",)), "--area", "0.1"], "unknown column(s) Fu, Fv, Mz"),
        ([*base, table("point", drop=("heading",))], "--area is needed"),
        ([*base, table("point", drop=("heading",)), "--area", "0.1", "--inertia", "1"], "--inertia applies"),
    ]
    for argv, message in bad:
        with pytest.raises(SystemExit) as info:
            main(argv)
        err = capsys.readouterr().err
        assert info.value.code == 2, argv
        assert err.startswith("error: ") and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "out.h5").exists()


def test_an_imported_turning_table_trains_and_evaluates_from_the_command_line(
    fine_planar, tmp_path, capsys
) -> None:
    """``fhnn import`` (heading) → ``fhnn turning train`` → ``evaluate --json``: forecasts scored
    against the table's observations, the library's numbers."""
    import json

    from fhnn.api.planar import evaluate_turning, load_turning
    from fhnn.cli.app import main
    from fhnn.data.planar import read_planar
    from fhnn.data.planar_table import observed_table
    from fhnn.data.table import write_table

    table = write_table(
        observed_table(fine_planar, position_noise=1e-3, steps=(3, 7), seed=6), tmp_path / "t.csv"
    )
    data, folder = tmp_path / "d.h5", tmp_path / "run"
    for argv in (
        ["import", str(table), "-o", str(data), "--mass", "10", "--inertia", "1"],
        ["turning", "train", str(data), "-o", str(folder), "--adam-steps", "20", "--lbfgs-steps", "0", "-q"],
        ["turning", "evaluate", str(folder), str(data), "--horizon", "3", "--json"],
    ):
        capsys.readouterr()
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 0, argv
    report = json.loads(capsys.readouterr().out)
    assert "damping" not in report and "true" not in report["added_mass"]["m_22"]
    again = evaluate_turning(load_turning(folder), read_planar(data), horizon=3.0)
    assert report["forecast"]["rmse_pos"] == pytest.approx(again["forecast"]["rmse_pos"], rel=1e-12)
