"""A turning body under logged controls (issue 71): the table's controls reach the model where
known forces would, the learned actuator map's field is the body's under the mapped force, its
derivatives match central differences, training learns the map, and bad control tables are
refused in one line."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest

from fhnn.errors import DataFormatError

CONTROLS = {"Fu": "rudder", "Fv": "rpm", "Mz": "trim"}


@pytest.fixture(scope="module")
def turning():
    """20 trajectories of 6 s in a weak vortex (Γ = 0.5 m²/s), every 0.1 s."""
    from fhnn.data.planar import simulate_planar
    from fhnn.physics.planar_scenarios import get_planar_scenario

    scenario = get_planar_scenario("turning_vortex", gamma=0.5)
    return simulate_planar(
        scenario, n_traj=20, duration=6.0, test_duration=6.0, dt=0.1, seed=7, split=(0.6, 0.2, 0.2)
    )


@pytest.fixture(scope="module")
def controlled_frame(turning):
    """A noise-free table whose forces are given as three 'controls' (the map is the identity)."""
    from fhnn.data.planar_table import observed_table

    return pd.DataFrame(observed_table(turning, steps=(1, 2), seed=1)).rename(columns=CONTROLS)


def test_controls_travel_in_the_forces_channel(controlled_frame) -> None:
    from fhnn.api.planar import import_turning
    from fhnn.api.planar_controls import import_controlled

    forces = controlled_frame.rename(columns={v: k for k, v in CONTROLS.items()})
    known = import_turning(forces, mass=10.0, inertia=1.0, seed=2)
    data = import_controlled(controlled_frame, ["rudder", "rpm"], mass=10.0, inertia=1.0, seed=2)
    assert data.controls == ("rudder", "rpm")
    for name in ("train", "val", "test"):
        a, b = known.splits[name], data.dataset.splits[name]
        np.testing.assert_array_equal(b.forces[..., :2], a.forces[..., :2])
        assert np.all(b.forces[..., 2] == 0.0)
        np.testing.assert_array_equal(b.states, a.states)
    renamed = controlled_frame.rename(columns={"t": "time"})
    again = import_controlled(renamed, ["rudder", "rpm"], mass=10.0, inertia=1.0, seed=2, columns="t=time")
    np.testing.assert_array_equal(again.dataset.splits["train"].forces, data.dataset.splits["train"].forces)


def _model(dataset, n_controls=2, seed=0):
    import equinox as eqx

    from fhnn.models.planar import PlanarModelConfig
    from fhnn.models.planar_actuated import build_actuated_fhnn

    model = build_actuated_fhnn(
        PlanarModelConfig(width=8, depth=2), dataset, n_controls, key=jax.random.PRNGKey(seed)
    )
    leaves, treedef = jax.tree_util.tree_flatten(eqx.filter(model, eqx.is_inexact_array))
    keys = jax.random.split(jax.random.PRNGKey(seed + 1), len(leaves))
    noisy = [x + 0.3 * jax.random.normal(k, x.shape) for x, k in zip(leaves, keys, strict=True)]
    return eqx.combine(jax.tree_util.tree_unflatten(treedef, noisy), model)


def test_the_actuated_field_is_the_body_under_the_mapped_force(turning) -> None:
    """``f(s, t, c) = body(s, t, A(ν_r, c))``; the field's derivatives in the state and the
    controls match central differences; a third slot beyond two controls is ignored."""
    from fhnn.physics.planar import water_at_body

    model = _model(turning)
    s = jnp.array([0.9, -0.6, 0.4, 0.3, -0.1, 0.2])
    c = jnp.array([0.2, -0.1, 0.0])
    nu_r = s[3:] - water_at_body(model.body.flow, s[:3], 1.3)
    tau = model.actuator(nu_r, c[:2])
    np.testing.assert_allclose(model(s, 1.3, c), model.body(s, 1.3, tau), rtol=1e-14, atol=1e-14)
    np.testing.assert_array_equal(model(s, 1.3, c.at[2].set(5.0)), model(s, 1.3, c))
    assert np.all(np.abs(np.asarray(tau)) > 0)
    h = 1e-6
    for arg, x in ((0, s), (2, c)):

        def f(v, arg=arg):
            return model(v, 1.3, c) if arg == 0 else model(s, 1.3, v)

        jac = np.asarray(jax.jacfwd(f)(x))
        for j in range(x.size):
            e = jnp.zeros(x.size).at[j].set(h)
            fd = (np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h)
            np.testing.assert_allclose(jac[:, j], fd, rtol=1e-6, atol=1e-8)


def test_training_learns_the_map_and_the_stored_run_forecasts_as_trained(
    controlled_frame, tmp_path, capsys
) -> None:
    """The controls are the forces themselves: 500 Adam steps take the one-step validation loss
    below a tenth of the untrained model's, and held-out forecasts over 5 s within 5 cm (the test
    trajectories end 0.2-0.8 m from their starts). The run folder loads to identical weights and
    ``fhnn turning evaluate`` on it gives the API's numbers; the known-force functions refuse the
    run and the data, and a run is not scored on other controls."""
    from fhnn.api.planar import evaluate_turning, load_turning
    from fhnn.api.planar_controls import evaluate_controlled, import_controlled
    from fhnn.api.planar_controls_files import evaluate_controlled_run, load_controlled, train_controlled_run
    from fhnn.data.planar import read_planar
    from fhnn.data.planar_controls_file import write_controlled
    from fhnn.models.planar import PlanarModelConfig
    from fhnn.models.planar_actuated import build_actuated_fhnn
    from fhnn.training.planar import PlanarTrainConfig, _pairs, rate_scales, step_residuals
    from tests.conftest import arrays, run_cli

    data = import_controlled(controlled_frame, list(CONTROLS.values()), mass=10.0, inertia=1.0, seed=2)
    model_config = PlanarModelConfig(width=16, depth=2)
    training = PlanarTrainConfig(adam_steps=500, lbfgs_steps=0, validate_every=100, seed=0)
    run = tmp_path / "run"
    fit = train_controlled_run(data, run, model=model_config, training=training)
    start = build_actuated_fhnn(model_config, data.dataset, 3, key=jax.random.PRNGKey(0))
    val = data.dataset.splits["val"]
    scales = rate_scales(data.dataset.splits["train"])
    before = float(jnp.mean(step_residuals(start, _pairs(val), scales, 1) ** 2))
    assert fit.val_loss < before / 10
    errors = evaluate_controlled(fit.model, data, horizon=5.0)
    assert errors["diverged"] == 0 and errors["rmse_pos"] < 0.05
    # stored and loaded: the same weights, the same controls
    loaded, controls = load_controlled(run)
    assert controls == tuple(CONTROLS.values()) and loaded.n_controls == 3
    for a, b in zip(arrays(loaded), arrays(fit.model), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # and the same field: the skeleton load_controlled reads into is built as the trained one is
    state, t, c = jnp.array([0.3, -0.2, 0.4, 0.2, -0.1, 0.3]), jnp.asarray(1.0), jnp.array([0.5, -0.2, 0.1])
    np.testing.assert_array_equal(np.asarray(loaded(state, t, c)), np.asarray(fit.model(state, t, c)))
    # the command scores the stored run on the stored data as the API scores the trained model
    path = write_controlled(data.dataset, data.controls, tmp_path / "controls.h5")
    code, out, err = run_cli(["turning", "evaluate", str(run), str(path), "--horizon", "5", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["forecast"] == errors
    assert evaluate_controlled_run(run, path, horizon=5.0)["forecast"] == errors
    # the known-force readers refuse what would be read as forces
    with pytest.raises(DataFormatError, match="not a turning body's data set"):
        read_planar(path)
    with pytest.raises(DataFormatError, match="not a turning model"):
        load_turning(run)
    with pytest.raises(DataFormatError, match="not a turning body's data set"):
        evaluate_turning(fit.model.body, path)
    other = write_controlled(data.dataset, ("rudder", "rpm", "flap"), tmp_path / "other.h5")
    code, _, err = run_cli(["turning", "evaluate", str(run), str(other)], capsys)
    assert code == 2 and "was trained on controls rudder, rpm, trim; the data hold rudder, rpm, flap" in err


def test_the_import_command_takes_controls_and_the_train_command_learns_their_map(
    controlled_frame, tmp_path, capsys
) -> None:
    """``fhnn import --controls`` writes what :func:`import_controlled` makes (the controls' own
    kind of file); ``fhnn turning train`` on it trains a model of controls (here no steps: the
    routing is what is checked); misplaced options are refused in one line, nothing written."""
    from fhnn.api.planar_controls import import_controlled
    from fhnn.api.planar_controls_files import is_controlled_run, load_controlled, read_controlled_data
    from tests.conftest import run_cli

    table = tmp_path / "trials.csv"
    controlled_frame.to_csv(table, index=False)
    out = tmp_path / "trials.h5"
    base = ["import", str(table), "-o", str(out), "--mass", "10", "--inertia", "1", "--seed", "2"]
    code, _, err = run_cli([*base, "--controls", "rudder, rpm,trim"], capsys)
    assert code == 0, err
    assert "a turning body's data set under controls rudder, rpm, trim" in " ".join(err.split())
    stored = read_controlled_data(out)
    expected = import_controlled(table, list(CONTROLS.values()), mass=10.0, inertia=1.0, seed=2)
    assert stored.controls == expected.controls
    for name, split in expected.dataset.splits.items():
        for key in ("t", "states", "states_clean", "forces", "lengths"):
            np.testing.assert_array_equal(getattr(stored.dataset.splits[name], key), getattr(split, key))
    code, said, err = run_cli(["info", str(out), "--json"], capsys)
    described = json.loads(said)
    assert code == 0 and described["controls"] == list(CONTROLS.values())
    for name, split in expected.dataset.splits.items():
        assert described["splits"][name]["samples"] == int(split.lengths.sum())
    states = expected.dataset.splits["train"].states[expected.dataset.splits["train"].valid()]
    assert described["covered"]["r"] == [states[:, 5].min(), states[:, 5].max()]
    run = tmp_path / "run"
    code, said, err = run_cli(
        ["turning", "train", str(out), "-o", str(run), "--adam-steps", "0", "--lbfgs-steps", "0"], capsys
    )
    assert code == 0, err
    assert "a map from the controls to forces learned" in said and is_controlled_run(run)
    assert load_controlled(run)[1] == tuple(CONTROLS.values())
    forecast = tmp_path / "forecast.parquet"
    predict = [
        "turning",
        "predict",
        str(run),
        "--history",
        str(table),
        "-o",
        str(forecast),
        "--duration",
        "0.5",
    ]
    code, said, err = run_cli(predict, capsys)
    assert code == 0 and f"wrote {forecast}: 20 tracks continued 0.5 s" in " ".join(err.split()), err
    continued = pd.read_parquet(forecast)
    last = controlled_frame.sort_values("t").groupby("traj_id")["t"].max()
    assert (continued.groupby("traj_id")["t"].min() == last.loc[continued["traj_id"].unique()]).all()
    controlled_frame.drop(columns="trim").to_csv(tmp_path / "no_trim.csv", index=False)
    code, _, err = run_cli([*predict[:4], str(tmp_path / "no_trim.csv"), *predict[5:]], capsys)
    assert code == 2 and "no control column 'trim'" in err
    code, _, err = run_cli(["turning", "inspect", str(run), str(out)], capsys)
    assert code == 2 and "a model of logged controls, whose added masses and damping" in err
    refused = [
        (
            [*base, "--controls", "rudder", "--time-dependent"],
            "--time-dependent does not apply with --controls",
        ),
        ([*base, "--controls", "rudder,fins"], "no control column 'fins'"),
        ([*base, "--controls", "rudder", "--area", "1"], "--area and --forcing apply to a table without"),
    ]
    flat = tmp_path / "flat.csv"
    controlled_frame.drop(columns="heading").to_csv(flat, index=False)
    flat_args = ["import", str(flat), "-o", str(out), "--mass", "10", "--area", "1", "--controls", "rudder"]
    refused.append((flat_args, "--controls applies to a table with a heading column"))
    out.unlink()
    for argv, message in refused:
        code, _, err = run_cli(argv, capsys)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
        assert not out.exists()


@pytest.mark.parametrize(
    ("controls", "change", "message"),
    [
        ([], None, "give one to 3 control columns, got 0"),
        (["rudder", "rpm", "trim", "flap"], None, "give one to 3 control columns, got 4"),
        (["rudder", "rudder"], None, "a control column is named twice"),
        (["x"], None, "'x' is a column of the turning body's table, not a control"),
        (["rudder", "fins"], None, "no control column 'fins'"),
        (["rudder"], {"rudder": "port"}, "control column 'rudder' is not numeric"),
        (["rudder"], {"Fu": 1.0}, "gives forces (Fu) and controls; give one of them"),
    ],
)
def test_bad_control_tables_are_refused_in_one_line(controlled_frame, controls, change, message) -> None:
    from fhnn.api.planar_controls import import_controlled

    frame = controlled_frame.assign(**change) if change else controlled_frame
    with pytest.raises(DataFormatError) as info:
        import_controlled(frame, controls, mass=10.0, inertia=1.0)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_control_table_on_disk_is_read_and_a_wrong_file_is_refused(controlled_frame, tmp_path) -> None:
    from fhnn.data.planar_controls import controls_as_forcing

    path = tmp_path / "trials.csv"
    controlled_frame.to_csv(path, index=False)
    forcing = controls_as_forcing(path, ["rpm"])
    np.testing.assert_array_equal(forcing["Fu"], controlled_frame["rpm"])
    assert list(forcing.columns) == ["traj_id", "t", "x", "y", "heading", "Fu", "Fv", "Mz"]
    with pytest.raises(DataFormatError, match="no such file"):
        controls_as_forcing(tmp_path / "none.csv", ["rpm"])
    (tmp_path / "trials.txt").write_text("a,b\n")
    with pytest.raises(DataFormatError, match=r"a table is a \.csv or \.parquet file"):
        controls_as_forcing(tmp_path / "trials.txt", ["rpm"])
